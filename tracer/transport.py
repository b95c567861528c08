"""Forward photon tracing: photons from the sources through the scene, tallied by the sensors they cross.

This is the paper's scheme (section 4): a photon leaves a source; the top level finds the candidate
instances and their bottom levels the closest hit (`tracer.traverse.intersect_closest`); on the way
the current medium absorbs (continuous weight exp(−σa t)) or scatters it (free-flight sampling,
Henyey–Greenstein); every sensor the segment crosses records the photon's weight if it arrives on
its front side (`sensor_crossings_with_stack`; sensors change nothing); at the surface the material reflects,
refracts or absorbs it and sets the medium it continues in (a stack of the solids it is inside).

Estimation. A photon's weight is luminous flux (lm): Φ_total / N × f at emission (see
`tracer.sources`). Surfaces act analogously (a photon is reflected with probability ρ, keeping its
weight), Fresnel interfaces choose reflection with probability R, so weights change only through
media absorption and Russian roulette: below 1 % of its initial weight, or after `RR_DEPTH`
bounces, a photon survives with probability q and its weight is divided by q — unbiased. A path
longer than `MAX_BOUNCES` is cut and counted (`truncated`). A non-finite weight or direction is never
tallied: the photon is dropped and counted (`rejected`).

Specialisation. `forward_batches` takes the four effect flags of `tracer.effects.Flags`, each None
(effect off: the branch is pruned at compile time) or True; numba compiles and caches one variant
per combination actually used.

Counters (per batch, `COUNTERS`): rejected, truncated, medium stack overflow, sensor buffer full,
unsupported material (a material whose effect was not compiled in: absorbed and counted).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from tracer.media import hg_scatter, sample_free_flight, transmittance
from tracer.rng import path_key, uniform
from tracer.sources import pick_light, sample_emission
from tracer.spawn import offset_ray_origin
from tracer.surfaces import (
    DIELECTRIC,
    LAMBERTIAN,
    MIRROR,
    MIX,
    fresnel_dielectric,
    reflect,
    refract,
    sample_cosine,
)
from tracer.traverse import closest_with_stacks, new_stacks, sensor_crossings_with_stack, shading_normal

COUNTERS = ("rejected", "truncated", "stack_overflow", "sensor_buffer_full", "unsupported_material")
C_REJECTED, C_TRUNCATED, C_STACK, C_SENSOR_FULL, C_UNSUPPORTED = range(5)
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
def _arrival_normal(ngx, ngy, ngz, dx, dy, dz):
    """The geometric normal turned to the side the ray arrives from."""
    if dx * ngx + dy * ngy + dz * ngz > 0.0:
        return -ngx, -ngy, -ngz
    return ngx, ngy, ngz


@njit(cache=True, error_model="numpy", _nrt=False)
def _specular_normal(sa, inst, prim, hu, hv, fx, fy, fz):
    """Shading normal turned to the arrival side `f` (unit); the geometric one where they disagree."""
    sx, sy, sz = shading_normal(sa, inst, prim, hu, hv)
    if sx * fx + sy * fy + sz * fz < 0.0:
        sx, sy, sz = -sx, -sy, -sz
    if not (sx * fx + sy * fy + sz * fz > 0.0):
        return fx, fy, fz
    return sx, sy, sz


@njit(cache=True, error_model="numpy", _nrt=False)
def _reflect_specular(sa, inst, prim, hu, hv, dx, dy, dz, fx, fy, fz):
    """Specular reflection about the shading normal; about the geometric one if that would go below the surface."""
    nx, ny, nz = _specular_normal(sa, inst, prim, hu, hv, fx, fy, fz)
    rx, ry, rz = reflect(dx, dy, dz, nx, ny, nz)
    if rx * fx + ry * fy + rz * fz <= 0.0:
        rx, ry, rz = reflect(dx, dy, dz, fx, fy, fz)
    inv = 1.0 / math.sqrt(rx * rx + ry * ry + rz * rz)
    return rx * inv, ry * inv, rz * inv


@njit(cache=True, error_model="numpy", _nrt=False)
def _medium_ior(M, med, depth):
    return M.par[med[depth - 1], 0] if depth > 0 else 1.0


@njit(cache=True, error_model="numpy", _nrt=False)
def trace_photon(sa, M, L, S, key, w, tally, counters, med, c_inst, c_t, c_u, c_v, c_cos, stack, tstack,
                 specular, fresnel, absorption, scattering):
    """Trace one photon of initial weight `w` (lm) and add what sensors record to `tally`."""
    dim = 1
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
        if absorption is not None or scattering is not None:
            if depth > 0:
                mi = med[depth - 1]
                if absorption is not None:
                    sig_a = M.par[mi, 1]
                if scattering is not None:
                    sig_s = M.par[mi, 2]
                    if sig_s > 0.0:
                        ts = sample_free_flight(sig_s, uniform(key, dim))
                        dim += 1
                        if ts < t:
                            t_end = ts
                            scattered = True
        # sensors along (0, t_end): they record and change nothing
        nc = sensor_crossings_with_stack(sa, ox, oy, oz, dx, dy, dz, t_end, c_inst, c_t, c_u, c_v, c_cos, stack)
        if nc == c_inst.shape[0]:
            counters[C_SENSOR_FULL] += 1
        for c in range(nc):
            if c_cos[c] > 0.0:
                si = c_inst[c]
                b0 = S.bin0[si] if si < S.bin0.shape[0] else -1   # another query's sensors: not ours
                if b0 >= 0:
                    cu = min(max(int(c_u[c] * S.nu[si]), 0), S.nu[si] - 1)
                    cv = min(max(int(c_v[c] * S.nv[si]), 0), S.nv[si] - 1)
                    val = w
                    if absorption is not None:
                        val = w * transmittance(sig_a, c_t[c])
                    if math.isfinite(val):
                        tally[b0 + cv * S.nu[si] + cu] += val
                    else:
                        counters[C_REJECTED] += 1
        if absorption is not None:
            if sig_a > 0.0:
                if not math.isfinite(t_end):
                    return
                w = w * transmittance(sig_a, t_end)
        if scattered:
            ox = ox + t_end * dx
            oy = oy + t_end * dy
            oz = oz + t_end * dz
            dx, dy, dz = hg_scatter(dx, dy, dz, M.par[med[depth - 1], 3], uniform(key, dim), uniform(key, dim + 1))
            dim += 2
        else:
            if inst < 0:
                return
            px = ox + t * dx
            py = oy + t * dy
            pz = oz + t * dz
            kind = M.kind[inst]
            fx, fy, fz = _arrival_normal(ngx, ngy, ngz, dx, dy, dz)
            u = uniform(key, dim)
            dim += 1
            if kind == LAMBERTIAN:
                if u >= M.par[inst, 0]:
                    return
                dx, dy, dz = sample_cosine(fx, fy, fz, uniform(key, dim), uniform(key, dim + 1))
                dim += 2
            elif kind == MIRROR or kind == MIX:
                if specular is None and kind == MIRROR:
                    counters[C_UNSUPPORTED] += 1
                    return
                rd = M.par[inst, 0] if kind == MIX else 0.0
                rs = M.par[inst, 0] if kind == MIRROR else M.par[inst, 1]
                if u < rd:
                    dx, dy, dz = sample_cosine(fx, fy, fz, uniform(key, dim), uniform(key, dim + 1))
                    dim += 2
                elif u < rd + rs:
                    if specular is None:
                        counters[C_UNSUPPORTED] += 1
                        return
                    dx, dy, dz = _reflect_specular(sa, inst, prim, hu, hv, dx, dy, dz, fx, fy, fz)
                else:
                    return
            elif kind == DIELECTRIC:
                if fresnel is None:
                    counters[C_UNSUPPORTED] += 1
                    return
                entering = dx * ngx + dy * ngy + dz * ngz < 0.0
                pos = -1
                if entering:
                    n1 = _medium_ior(M, med, depth)
                    n2 = M.par[inst, 0]
                else:
                    n1 = M.par[inst, 0]
                    for k in range(depth - 1, -1, -1):
                        if med[k] == inst:
                            pos = k
                            break
                    if pos >= 0:
                        n2 = M.par[med[pos - 1], 0] if pos > 0 else 1.0
                    elif depth > 0 and med[depth - 1] != inst:
                        n2 = _medium_ior(M, med, depth)   # leaving a solid it was not known to be in
                    else:
                        n2 = 1.0
                snx, sny, snz = _specular_normal(sa, inst, prim, hu, hv, fx, fy, fz)
                cos_i = -(dx * snx + dy * sny + dz * snz)
                r = fresnel_dielectric(cos_i, n1, n2)
                transmitted = False
                if u < r:
                    dx, dy, dz = _reflect_specular(sa, inst, prim, hu, hv, dx, dy, dz, fx, fy, fz)
                elif n1 == n2:
                    transmitted = True   # index-matched: straight on, no spurious bending
                else:
                    ok, tx, ty, tz = refract(dx, dy, dz, snx, sny, snz, n1 / n2)
                    if not ok or tx * fx + ty * fy + tz * fz >= 0.0:
                        ok, tx, ty, tz = refract(dx, dy, dz, fx, fy, fz, n1 / n2)
                    if ok:
                        dx, dy, dz = tx, ty, tz
                        transmitted = True
                    else:   # rounding at the critical angle: total internal reflection
                        dx, dy, dz = _reflect_specular(sa, inst, prim, hu, hv, dx, dy, dz, fx, fy, fz)
                if transmitted:
                    if entering:
                        if depth == med.shape[0]:
                            counters[C_STACK] += 1
                            return
                        med[depth] = inst
                        depth += 1
                    elif pos >= 0:
                        for k in range(pos, depth - 1):
                            med[k] = med[k + 1]
                        depth -= 1
            else:   # BLACK, or an id without material
                return
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


@njit(parallel=True, cache=True, error_model="numpy")
def forward_batches(sa, M, L, S, n_bins, seed, batch0, n_batches, photons, specular, fresnel, absorption, scattering):
    """Run batches batch0 … batch0+n_batches−1 of `photons` photons each.

    Returns
    -------
    flux : (n_batches, n_bins) float64
        Flux in lm each bin recorded in each batch (the batch's estimate of the bin's flux).
    counters : (n_batches, 5) int64
        See `COUNTERS`.

    Batches run in parallel (one thread each); photons within a batch run in order, so a batch's
    sums do not depend on the number of threads.
    """
    out = np.zeros((n_batches, n_bins))
    cnt = np.zeros((n_batches, len(COUNTERS)), np.int64)
    w0 = L.flux_total[0] / photons
    for b in prange(n_batches):
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
            trace_photon(sa, M, L, S, key, w0, tally, counters, med, c_inst, c_t, c_u, c_v, c_cos, stack, tstack,
                         specular, fresnel, absorption, scattering)
    return out, cnt
