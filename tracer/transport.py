"""Forward photon tracing: photons from the sources through the scene, tallied by the sensors they cross.

This is the paper's scheme (section 4): a photon leaves a source; the top level finds the candidate
instances and their bottom levels the closest hit (`tracer.traverse.intersect_closest`); on the way
the current medium absorbs (continuous weight exp(−σa t)) or scatters it (free-flight sampling,
Henyey–Greenstein); every sensor the segment crosses records the photon's weight if it arrives on
its front side (`sensor_crossings_with_stack`; sensors change nothing); at the surface the material reflects,
refracts or absorbs it and sets the medium it continues in (a stack of the solids it is inside).

Estimation. A photon's weight is luminous flux (lm): Φ_total / N × f at emission (see
`tracer.optics.lights`). Surfaces act analogously (a photon is reflected with probability ρ, keeping its
weight), Fresnel interfaces choose reflection with probability R, so weights change only through
media absorption and Russian roulette: below 1 % of its initial weight, or after `RR_DEPTH`
bounces, a photon survives with probability q and its weight is divided by q — unbiased. A path
longer than `MAX_BOUNCES` is cut and counted (`truncated`). A non-finite weight or direction is never
tallied: the photon is dropped and counted (`rejected`).

Optics. What a surface does is asked of `tracer.optics.surfaces.dispatch.scatter`, what a medium does
of `tracer.optics.media.dispatch`, where a photon starts of `tracer.optics.lights`: this kernel never
switches on a kind. Receivers are the query's own: a small structure of sensor instances (`ra`, the
arrays of a `tracer.Scene` that holds only them) beside the read-only scene `sa`; a query never adds
anything to the scene it reads.

One kernel per photon state (`forward_kernel`, `tracer.effects.photon_state`); the effects of a scene
are branches on its data, compiled in once.

Counters (per batch, `COUNTERS`): rejected, truncated, medium stack overflow, sensor buffer full.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from tracer.optics.lights import pick_light, sample_emission
from tracer.optics.media.dispatch import medium_coefficients, medium_scatter
from tracer.optics.media.homogeneous import sample_free_flight, transmittance
from tracer.optics.surfaces.base import ABSORBED, STACK_FULL
from tracer.optics.surfaces.dispatch import scatter
from tracer.rng import path_key, uniform
from tracer.spawn import offset_ray_origin
from tracer.traverse import closest_with_stacks, new_stacks, sensor_crossings_with_stack

COUNTERS = ("rejected", "truncated", "stack_overflow", "sensor_buffer_full")
C_REJECTED, C_TRUNCATED, C_STACK, C_SENSOR_FULL = range(4)
RR_DEPTH = 64          # bounces after which every photon plays Russian roulette
RR_SURVIVE = 0.9       # its survival probability there
RR_WEIGHT = 0.01       # fraction of the initial weight below which a photon plays roulette
MAX_BOUNCES = 100_000  # a longer path is cut and counted
MEDIUM_DEPTH = 8       # nested solids a photon may be inside
SENSOR_CAP = 64        # sensor crossings recorded per segment (the nearest ones)


class SensorArrays(NamedTuple):
    """Which instance is a tallied sensor and where it tallies.

    bin0 (n_inst,) int64: first bin of the sensor, −1 for other instances; nu, nv (n_inst,) int64:
    cells of a rect sensor along u and v (1, 1 for a disk); the bin of a crossing at (u, v) is
    bin0 + min(⌊v nv⌋, nv−1) nu + min(⌊u nu⌋, nu−1).
    """

    bin0: np.ndarray
    nu: np.ndarray
    nv: np.ndarray


@njit(cache=True, error_model="numpy", _nrt=False)
def trace_photon(sa, ra, M, L, S, key, w, tally, counters, med, c_inst, c_t, c_u, c_v, c_cos, stack, tstack):
    """Trace one photon of initial weight `w` (lm) and add what the receivers record to `tally`."""
    j, pj = pick_light(L, uniform(key, 0))
    ox, oy, oz, dx, dy, dz, f, on_surface, nx, ny, nz = sample_emission(
        L, j, uniform(key, 1), uniform(key, 2), uniform(key, 3), uniform(key, 4), uniform(key, 5))
    dim = 6
    w = w * f
    if on_surface:
        ox, oy, oz = offset_ray_origin(ox, oy, oz, nx, ny, nz, dx, dy, dz)
    if not (math.isfinite(w) and math.isfinite(dx + dy + dz) and math.isfinite(ox + oy + oz)):
        counters[C_REJECTED] += 1
        return
    if w <= 0.0:
        return
    w_init = w
    depth = 0
    bounce = 0
    while True:
        t, inst, prim, hu, hv, ngx, ngy, ngz = closest_with_stacks(sa, ox, oy, oz, dx, dy, dz, math.inf, stack, tstack)
        t_end = t
        scattered = False
        sig_a = 0.0
        if depth > 0:
            sig_a, sig_s = medium_coefficients(M, med[depth - 1])
            if sig_s > 0.0:
                ts = sample_free_flight(sig_s, uniform(key, dim))
                dim += 1
                if ts < t:
                    t_end = ts
                    scattered = True
        # receivers along (0, t_end): they record and change nothing
        nc = sensor_crossings_with_stack(ra, ox, oy, oz, dx, dy, dz, t_end, c_inst, c_t, c_u, c_v, c_cos, stack)
        if nc == c_inst.shape[0]:
            counters[C_SENSOR_FULL] += 1
        for c in range(nc):
            if c_cos[c] > 0.0:
                si = c_inst[c]
                b0 = S.bin0[si]
                cu = min(max(int(c_u[c] * S.nu[si]), 0), S.nu[si] - 1)
                cv = min(max(int(c_v[c] * S.nv[si]), 0), S.nv[si] - 1)
                val = w * transmittance(sig_a, c_t[c])
                if math.isfinite(val):
                    tally[b0 + cv * S.nu[si] + cu] += val
                else:
                    counters[C_REJECTED] += 1
        if sig_a > 0.0:
            if not math.isfinite(t_end):
                return
            w = w * transmittance(sig_a, t_end)
        if scattered:
            ox = ox + t_end * dx
            oy = oy + t_end * dy
            oz = oz + t_end * dz
            dx, dy, dz = medium_scatter(M, med[depth - 1], dx, dy, dz, uniform(key, dim), uniform(key, dim + 1))
            dim += 2
        else:
            if inst < 0:
                return
            px = ox + t * dx
            py = oy + t * dy
            pz = oz + t * dz
            status, dx, dy, dz, f, depth, dim = scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz,
                                                        med, depth, key, dim)
            if status == ABSORBED:
                return
            if status == STACK_FULL:
                counters[C_STACK] += 1
                return
            w = w * f
            ox, oy, oz = offset_ray_origin(px, py, pz, ngx, ngy, ngz, dx, dy, dz)
        if not (math.isfinite(dx + dy + dz) and math.isfinite(ox + oy + oz) and math.isfinite(w)):
            counters[C_REJECTED] += 1
            return
        bounce += 1
        if bounce >= MAX_BOUNCES:
            counters[C_TRUNCATED] += 1
            return
        # Russian roulette: unbiased, bounds path length and ends photons a medium has nearly absorbed
        q = 1.0
        if w < RR_WEIGHT * w_init:
            q = w / (RR_WEIGHT * w_init)
        if bounce >= RR_DEPTH:
            q = min(q, RR_SURVIVE)
        if q < 1.0:
            if uniform(key, dim) >= q:
                return
            dim += 1
            w = w / q


@njit(cache=True, error_model="numpy", nogil=True)
def forward_batches(sa, ra, M, L, S, n_bins, seed, batch0, n_batches, photons):
    """Run batches batch0 … batch0+n_batches−1 of `photons` photons each.

    Returns
    -------
    flux : (n_batches, n_bins) float64
        Flux in lm each bin recorded in each batch (the batch's estimate of the bin's flux).
    counters : (n_batches, len(COUNTERS)) int64
        See `COUNTERS`.

    Serial and without the GIL: `tracer.simulate` runs contiguous runs of batches on threads. Each batch
    is seeded by its index and its photons run in order, so its sums do not depend on the threads.
    """
    out = np.zeros((n_batches, n_bins))
    cnt = np.zeros((n_batches, len(COUNTERS)), np.int64)
    w0 = L.flux_total[0] / photons
    for b in range(n_batches):
        med = np.empty(MEDIUM_DEPTH, np.int64)
        c_inst = np.empty(SENSOR_CAP, np.int64)
        c_t = np.empty(SENSOR_CAP)
        c_u = np.empty(SENSOR_CAP)
        c_v = np.empty(SENSOR_CAP)
        c_cos = np.empty(SENSOR_CAP)
        stack, tstack = new_stacks()
        tally = out[b]
        counters = cnt[b]
        for i in range(photons):
            key = path_key(seed, batch0 + b, i)
            trace_photon(sa, ra, M, L, S, key, w0, tally, counters, med, c_inst, c_t, c_u, c_v, c_cos, stack, tstack)
    return out, cnt


def forward_kernel(state: str):
    """The forward kernel for a photon state (`tracer.effects.photon_state`): the one factory of kernels."""
    if state == "white":
        return forward_batches
    raise ValueError(f"no forward kernel for the photon state {state!r}")
