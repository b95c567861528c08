"""Forward photon tracing: photons from the sources through the scene, tallied by the sensors they cross.

This is the paper's scheme (section 4): a photon leaves a source; the top level finds the candidate
instances and their bottom levels the closest hit (`tracer.accel.traverse.intersect_closest`); on the way
the current medium absorbs (continuous weight exp(−σa t)) or scatters it (free-flight sampling,
Henyey–Greenstein); every sensor the segment crosses records the photon's weight if it arrives on
its front side (`sensor_crossings_with_stack`; sensors change nothing); at the surface the surface tally
records the weight arriving on the front side of the triangle hit where the query asks for it
(`SensorArrays.surf`; it changes nothing either), then the material reflects, refracts or absorbs it and sets
the medium it continues in (a stack of the solids it is inside). A photon whose ray meets nothing leaves the
scene: the far-field tally records its weight by direction where the query asks for it (`SensorArrays.far`).

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

Photon state (`tracer.effects.photon_state`). A white photon carries luminous flux (lm). In the spectral
state (a scene whose materials depend on λ, or a query that observes the spectrum) a photon carries
radiant power (W) and a wavelength λ drawn from its light's spectrum (`tracer.optics.spectra`); the
materials read their values at λ, fluorescence may change it, and a receiver records K_m V(λ) × power
(lm), with the CIE 1931 tristimulus weights and 5 nm bands where the query observes the spectrum. The
effects of a scene are branches on its data, compiled in once (`forward_kernel`).

Counters (per batch, `COUNTERS`): rejected, truncated, medium stack overflow, sensor buffer full.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from tracer.accel.spawn import offset_ray_origin
from tracer.accel.traverse import closest_with_stacks, new_stacks, sensor_crossings_with_stack
from tracer.effects import PHOTON_STATES
from tracer.elements.diffraction import OUTSIDE_TABLE
from tracer.jit import njit
from tracer.optics.lights import pick_light, sample_emission
from tracer.optics.lights.dispatch import emit_wavelength
from tracer.optics.media.dispatch import medium_coefficients, medium_event
from tracer.optics.media.homogeneous import sample_free_flight, transmittance
from tracer.optics.polarization import N_POL, emit, observed
from tracer.optics.spectra import BIN_NM, LAMBDA_MIN, N_BINS, XBAR_GRID, ZBAR_GRID, grid_value, luminous
from tracer.optics.surfaces.base import ABSORBED, STACK_FULL
from tracer.optics.surfaces.dispatch import scatter
from tracer.rng import path_key, uniform

COUNTERS = ("rejected", "truncated", "stack_overflow", "sensor_buffer_full", "grating_outside_table")
C_REJECTED, C_TRUNCATED, C_STACK, C_SENSOR_FULL, C_GRATING = range(5)
RR_DEPTH = 256         # bounces after which every photon plays Russian roulette (64 made a stack of 20 plates,
                       # 40 interfaces, a heavy-tailed estimate: 21 % error on 100k photons against 0.3 % now)
RR_SURVIVE = 0.9       # its survival probability there
RR_WEIGHT = 0.01       # fraction of the initial weight below which a photon plays roulette
MAX_BOUNCES = 100_000  # a longer path is cut and counted
MEDIUM_DEPTH = 8       # nested solids a photon may be inside
SENSOR_CAP = 64        # sensor crossings recorded per segment (the nearest ones)
DIM_LAMBDA = 1 << 40   # the random dimension a photon's wavelength is drawn from: off the path's own, so that
                       # carrying a wavelength changes no other draw (same paths through a grey scene)


class SensorArrays(NamedTuple):
    """Which instance is a tallied sensor and where it tallies.

    bin0 (n_inst,) int64: first bin of the sensor, −1 for other instances; nu, nv (n_inst,) int64:
    cells of a rect sensor along u and v (1, 1 for a disk); the bin of a crossing at (u, v) is
    bin0 + min(⌊v nv⌋, nv−1) nu + min(⌊u nu⌋, nu−1). observe (2,) int64: [spectrum, stokes], 1 where the
    receivers also record it (`tally_columns`). ref (n_inst, 3) float64: each receiver's polarization reference
    axis (world, in its plane; read where it records Stokes).

    surf (n_scene_inst,) int64, indexed by the *scene's* instance ids (not the receivers'): the surface tally
    (`Simulation.surface`). surf[inst] ≥ 0 is the first bin of that instance's triangles: a photon that hits
    triangle `prim` of `inst` on its front side (the side its geometric normal points to, the outside of a CAD
    solid: d · n_g < 0) adds its weight (lm, the luminous value of a photon that carries a wavelength) to
    column 0 of bin surf[inst] + prim before the surface scatters it; −1 tallies nothing there, and so does an
    instance id past its end. It observes and changes nothing (no random draw, no weight, no path). Empty (the
    default) costs one comparison per surface hit.

    far (FAR_PARAMS,) float64 or empty: the far-field tally (`Simulation.far_field`). A photon that leaves the scene
    (its ray meets nothing) adds its weight (lm) to the bin of its direction on a C-γ grid, and to a last bin that
    holds the total flux leaving: [first bin, nc, nγ, the γ = 0 axis (3), the C = 0 axis (3), the C = 90° axis (3)]
    (unit, orthonormal). γ sample j = j Δγ (Δγ = 180°/(nγ−1)) owns the directions with γ in [γ_j − Δγ/2, γ_j + Δγ/2]
    ∩ [0°, 180°], C sample i = i ΔC (ΔC = 360°/nc) those with C in [C_i − ΔC/2, C_i + ΔC/2) (mod 360°); a polar cap
    (j = 0 or nγ−1) is one bin, its C = 0 one. Bin: first + j nc + i; the total: first + nγ nc. Observes and changes
    nothing either; empty (the default) costs one comparison per photon that leaves.
    """

    bin0: np.ndarray
    nu: np.ndarray
    nv: np.ndarray
    observe: np.ndarray
    ref: np.ndarray
    surf: np.ndarray = np.empty(0, np.int64)
    far: np.ndarray = np.empty(0, np.float64)


FAR_PARAMS = 12   # len(SensorArrays.far) where the far field is tallied


def tally_columns(observe_spectrum: bool, observe_stokes: bool = False) -> int:
    """Tallies per bin: luminous flux (lm); with the spectrum also X and Z (CIE 1931 x̄, z̄ weighted radiant
    flux, W) and the radiant flux (W) in each 5 nm band of `tracer.optics.spectra` (`N_BINS`); with Stokes
    last the luminous S1, S2, S3 (lm) in the receiver's frame. The tally of column c of bin b is at
    c × n_bins + b."""
    return 1 + (2 + N_BINS if observe_spectrum else 0) + (3 if observe_stokes else 0)


@njit(cache=True, error_model="numpy", _nrt=False)
def trace_photons(sa, ra, M, L, S, n_bins, seed, batch, photons, w0, tally, counters, med, c_inst, c_t, c_u, c_v,
                  c_cos, stack, tstack, pol):
    """Trace the photons of one batch, each of initial weight `w0` (lm; W where they carry a wavelength), and add
    what the receivers record to `tally` (`tally_columns`).

    The photon loop lives here, not in the caller: a call passes the scene's, the materials' and the lights'
    tuples (some hundred words), which per photon cost the diffuse room 5 % (bench/bench_spectral.py)."""
    for i in range(photons):
        key = path_key(seed, batch, i)
        w = w0
        j, pj = pick_light(L, uniform(key, 0))
        ox, oy, oz, dx, dy, dz, f, on_surface, nx, ny, nz = sample_emission(
            L, j, uniform(key, 1), uniform(key, 2), uniform(key, 3), uniform(key, 4), uniform(key, 5))
        dim = 6
        lam = 0.0
        if L.spectral[0] != 0:
            lam, f_lam = emit_wavelength(L, j, uniform(key, DIM_LAMBDA))
            f = f * f_lam
        w = w * f
        if L.polarized[0] != 0:
            emit(pol, L.pol, j, dx, dy, dz)
        if on_surface:
            ox, oy, oz = offset_ray_origin(ox, oy, oz, nx, ny, nz, dx, dy, dz)
        if not (math.isfinite(w) and math.isfinite(dx + dy + dz) and math.isfinite(ox + oy + oz)):
            counters[C_REJECTED] += 1
            continue
        if w <= 0.0:
            continue
        w_init = w
        depth = 0
        bounce = 0
        while True:
            t, inst, prim, hu, hv, ngx, ngy, ngz = closest_with_stacks(sa, ox, oy, oz, dx, dy, dz, math.inf, stack,
                                                                       tstack)
            t_end = t
            scattered = False
            sig_a = 0.0
            sig_s = 0.0
            sig_f = 0.0
            if depth > 0:
                sig_a, sig_s, sig_f = medium_coefficients(M, med[depth - 1], lam)
                if sig_s + sig_f > 0.0:
                    ts = sample_free_flight(sig_s + sig_f, uniform(key, dim))
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
                    b = b0 + cv * S.nu[si] + cu
                    if not math.isfinite(val):
                        counters[C_REJECTED] += 1
                        continue
                    lm = val
                    if lam > 0.0:
                        lm = val * luminous(lam)
                        if S.observe[0] != 0:
                            record_spectrum(tally, n_bins, b, val, lam)
                    tally[b] += lm
                    if S.observe[1] != 0:
                        record_stokes(tally, n_bins * (1 + (2 + N_BINS) * S.observe[0]) + b, n_bins, lm, pol,
                                      dx, dy, dz, S.ref, si)
            if sig_a > 0.0:
                if not math.isfinite(t_end):
                    break
                w = w * transmittance(sig_a, t_end)
            if scattered:
                ox = ox + t_end * dx
                oy = oy + t_end * dy
                oz = oz + t_end * dz
                alive, dx, dy, dz, lam, f, dim = medium_event(M, med[depth - 1], dx, dy, dz, lam, sig_s, sig_f, key,
                                                              dim, pol)
                if not alive:
                    break
                w = w * f
            else:
                if inst < 0:
                    if S.far.shape[0] != 0:   # the far-field tally: the photon leaves the scene along d
                        record_far(tally, S.far, w * luminous(lam) if lam > 0.0 else w, dx, dy, dz)
                    break
                px = ox + t * dx
                py = oy + t * dy
                pz = oz + t * dz
                # the surface tally (`SensorArrays.surf`): the weight arriving on the front side, before it scatters
                # (on a triangle: a feature of an element with an inside has prim < -1 and no bin)
                if inst < S.surf.shape[0] and S.surf[inst] >= 0 and prim >= 0 and dx * ngx + dy * ngy + dz * ngz < 0.0:
                    sw = w
                    if lam > 0.0:
                        sw = w * luminous(lam)
                    if math.isfinite(sw):
                        tally[S.surf[inst] + prim] += sw
                status, dx, dy, dz, f, depth, dim = scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz,
                                                            med, depth, key, dim, lam, pol)
                if status == ABSORBED:
                    break
                if status == STACK_FULL:
                    counters[C_STACK] += 1
                    break
                if status == OUTSIDE_TABLE:   # it goes on; the answer says a grating's table ran out
                    counters[C_GRATING] += 1
                w = w * f
                ox, oy, oz = offset_ray_origin(px, py, pz, ngx, ngy, ngz, dx, dy, dz)
            if not (math.isfinite(dx + dy + dz) and math.isfinite(ox + oy + oz) and math.isfinite(w)):
                counters[C_REJECTED] += 1
                break
            bounce += 1
            if bounce >= MAX_BOUNCES:
                counters[C_TRUNCATED] += 1
                break
            # Russian roulette: unbiased, bounds path length and ends photons a medium has nearly absorbed
            q = 1.0
            if w < RR_WEIGHT * w_init:
                q = w / (RR_WEIGHT * w_init)
            if bounce >= RR_DEPTH:
                q = min(q, RR_SURVIVE)
            if q < 1.0:
                if uniform(key, dim) >= q:
                    break
                dim += 1
                w = w / q


@njit(cache=True, error_model="numpy", _nrt=False)
def record_far(tally, far, lm, dx, dy, dz):
    """Add `lm` lm leaving the scene along d to its far-field bin and to the total (`SensorArrays.far`)."""
    if not math.isfinite(lm):
        return
    nd = math.sqrt(dx * dx + dy * dy + dz * dz)
    if not nd > 0.0:
        return
    nc = int(far[1])
    ng = int(far[2])
    cg = (dx * far[3] + dy * far[4] + dz * far[5]) / nd
    gam = math.degrees(math.acos(min(1.0, max(-1.0, cg))))
    j = min(max(int(gam * (ng - 1) / 180.0 + 0.5), 0), ng - 1)
    i = 0
    if 0 < j < ng - 1:
        c = math.degrees(math.atan2(dx * far[9] + dy * far[10] + dz * far[11], dx * far[6] + dy * far[7] + dz * far[8]))
        if c < 0.0:
            c += 360.0
        i = int(c * nc / 360.0 + 0.5)
        if i >= nc:
            i -= nc
    b0 = int(far[0])
    tally[b0 + j * nc + i] += lm
    tally[b0 + ng * nc] += lm


@njit(cache=True, error_model="numpy", _nrt=False)
def record_spectrum(tally, n_bins, b, watts, lam):
    """Add a crossing of `watts` W at λ nm to bin b's spectral columns (`tally_columns`)."""
    tally[n_bins + b] += watts * grid_value(XBAR_GRID, lam)
    tally[2 * n_bins + b] += watts * grid_value(ZBAR_GRID, lam)
    band = min(max(int((lam - LAMBDA_MIN) / BIN_NM), 0), N_BINS - 1)
    tally[(3 + band) * n_bins + b] += watts


@njit(cache=True, error_model="numpy", _nrt=False)
def record_stokes(tally, at, n_bins, lm, pol, dx, dy, dz, ref, si):
    """Add a crossing of `lm` lm along d to the Stokes columns S1, S2, S3 of a bin (the first at index `at`, the
    next n_bins on), in the frame of receiver `si`: x axis ref[si] (`SensorArrays`) taken across d."""
    s1, s2, s3 = observed(pol, dx, dy, dz, ref[si, 0], ref[si, 1], ref[si, 2])
    tally[at] += lm * s1
    tally[at + n_bins] += lm * s2
    tally[at + 2 * n_bins] += lm * s3


@njit(cache=True, error_model="numpy", nogil=True)
def forward_batches(sa, ra, M, L, S, n_bins, seed, batch0, n_batches, photons):
    """Run batches batch0 … batch0+n_batches−1 of `photons` photons each.

    Returns
    -------
    flux : (n_batches, n_bins × tally_columns) float64
        Flux in lm each bin recorded in each batch (the batch's estimate of the bin's flux), then the
        spectral columns where `S.observe` asks for them (`tally_columns`).
    counters : (n_batches, len(COUNTERS)) int64
        See `COUNTERS`.

    Serial and without the GIL: `tracer.simulate` runs contiguous runs of batches on threads. Each batch
    is seeded by its index and its photons run in order, so its sums do not depend on the threads.
    """
    out = np.zeros((n_batches, n_bins * (1 + (2 + N_BINS) * S.observe[0] + 3 * S.observe[1])))
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
        pol = np.zeros(N_POL)
        tally = out[b]
        counters = cnt[b]
        trace_photons(sa, ra, M, L, S, n_bins, seed, batch0 + b, photons, w0, tally, counters, med, c_inst, c_t, c_u,
                      c_v, c_cos, stack, tstack, pol)
    return out, cnt


def forward_kernel(state: str):
    """The forward kernel for a photon state (`tracer.effects.photon_state`): the one factory of kernels.

    Every state shares one compiled kernel: a wavelength is one float and a branch per tally, a Stokes vector
    a small array read where ``pol[ON]`` is set, which the benchmarks measure within noise on white scenes
    (bench/bench_spectral.py, bench/bench_polarization.py), while a second variant would cost a compile (~40 s
    on 2 cores) the first time a scene turns spectral or polarized. Which state runs is data:
    `tracer.optics.lights.spectral_lights` and `polarized_lights` pack the lights for it."""
    if state in PHOTON_STATES:
        return forward_batches
    raise ValueError(f"no forward kernel for the photon state {state!r}")
