"""A query's rounds of batches: the stop rules, the round loop, and the forward and backward drivers.

`tracer.simulate.Simulation` turns a sensor's receivers (`tracer.sensors.base.Probe`) into one of these runs. Batches
are seeded from (seed, batch index); a round's size depends only on the request and the backend's
`tracer.backends.BatchShape`, so for the same seed and stop rule the answer is bit-identical wherever the batches of
one shape ran (see `tracer.simulate`'s docstring for the rules). Python orchestration only: the kernels are
`tracer.transport.forward`'s and `tracer.transport.backward`'s.
"""

from __future__ import annotations

import contextlib
import logging
import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from tracer.backends import CPU_SHAPE, IN_PROCESS, InProcess, Shipment
from tracer.compile_locks import first_use
from tracer.effects import photon_state
from tracer.errors import SimulationError
from tracer.gpu.device import DeviceUnavailable
from tracer.optics import spectra
from tracer.scene import Scene
from tracer.sensors.base import IlluminanceResult, Probe
from tracer.transport.backward import QueryArrays, disk_queries
from tracer.transport.estimate import Estimate, cost_of
from tracer.transport.forward import COUNTERS, SensorArrays, tally_columns
from tracer.transport.light_tracing import (
    C_LEFT,
    C_LIGHT_PATHS,
    C_LIGHT_RAYS,
    C_LIGHT_SPLATS,
    C_VIEW_RAYS,
    light_paths,
    no_light_paths,
)
from tracer.transport.query import Budget
from tracer.transport.radiance import COUNTERS as RADIANCE_COUNTERS
from tracer.transport.radiance import PIXEL, emitters

log = logging.getLogger(__name__)

ROUND_BATCHES = CPU_SHAPE.first_round        # batches started between two stop tests (the first rounds)
MAX_ROUND_BATCHES = CPU_SHAPE.max_round      # the largest round, however long the query has run
FORWARD_BATCH = CPU_SHAPE.forward_photons    # photons per forward batch (fewer when max_photons is small)
BACKWARD_BATCH = CPU_SHAPE.backward_paths    # paths per patch per backward batch
MIN_BATCHES = 8                # batches before the error bar is trusted for a target-error stop
MAX_ROUND_BYTES = 256 << 20    # a round's tallies (batches × bins × 8 B) stay below this: fewer batches a round
MAX_SPECTRAL_TALLIES = 4_000_000   # bins × spectral columns a query may record per batch
_COMPILE_SECONDS: dict[tuple, float] = {}   # first call of each compiled variant in this process


LIT_FRACTION = 0.01   # "lit" values: at least this fraction of the brightest one


def stop_error(est: Estimate, mean_est: Estimate, n_stop: int | None, scope: str) -> float:
    """The relative error a target is held to (`target_scope`): "worst", the largest over the values;
    "lit", the largest over the values at least `LIT_FRACTION` of the brightest (cells in shadow, which
    a handful of stray photons reach, cannot hold a grid to its target); "mean", that of the mean of
    the values (its batch means, `mean_est`)."""
    if scope == "mean":
        return float(mean_est.relative_error()[0])
    rel = est.relative_error()[:n_stop]
    if scope == "lit" and rel.size:
        mean = est.mean[:n_stop]
        top = float(np.max(mean))
        rel = rel[mean >= LIT_FRACTION * top] if top > 0 else rel[:0]
    return float(np.max(rel)) if rel.size else 0.0


class QueryBackend:
    """One query's backend: `backend`, then, once it says the card cannot take the query
    (`tracer.gpu.device.DeviceUnavailable`: a scene that does not fit), this process's CPU threads for the rest of
    the query; `describe()` then says so and why (``"fallback"``). The same batches, the same random numbers."""

    def __init__(self, backend: Any) -> None:
        self.backend = backend
        self.shape = backend.shape   # kept on the CPU too: the same batches
        self.fallback: str | None = None

    def run(self, kernel_id, scene, query, batch0, n_batches, size):
        if self.fallback is None:
            try:
                return self.backend.run(kernel_id, scene, query, batch0, n_batches, size)
            except DeviceUnavailable as exc:
                self.fallback = f"ran on the CPU because {exc}"
                log.warning("%s", self.fallback)
        return IN_PROCESS.run(kernel_id, scene, query, batch0, n_batches, size)

    def describe(self) -> dict[str, Any]:
        if self.fallback is None:
            return self.backend.describe()
        return {**IN_PROCESS.describe(), "fallback": self.fallback}


def warm(kernel_id: tuple, scene: Shipment, query: Shipment, backend: QueryBackend) -> float:
    """Compile (or load from cache) a kernel where it runs, on a one-photon batch; seconds it took, once per
    process and backend (waiting for a child process that compiles it, `tracer.warmup`, included)."""
    local = isinstance(backend.backend, InProcess)
    variant = kernel_id if local else (backend.backend.name, *kernel_id)
    if variant in _COMPILE_SECONDS:
        return 0.0
    t = time.perf_counter()
    with first_use(kernel_id[0]) if local else contextlib.nullcontext():
        backend.run(kernel_id, scene, query, 0, 1, 1)
    if backend.fallback is not None:   # it compiled for this process's CPU, not where it was asked
        variant = kernel_id
    _COMPILE_SECONDS.setdefault(variant, time.perf_counter() - t)
    return _COMPILE_SECONDS[variant]


def loop(run_round, n_bins, per_batch, budget, progress, cancel, t0, shape, n_stop=None):
    """Rounds of batches (`run_round(batch0, n) -> (values (n, n_bins), counters (n, c))`) until a stop rule
    holds; returns (Estimate, batches, stop_reason, counters).
    The error stop looks at the first `n_stop` bins (all by default): the illuminances, not the spectra.
    Rounds follow the backend's `shape`, and hold at most `MAX_ROUND_BYTES` of tallies."""
    max_round = max(2, min(shape.max_round, MAX_ROUND_BYTES // (8 * max(1, n_bins))))
    if progress is not None:   # before the first round: no photons yet, the seconds spent getting ready
        progress(0, math.inf, time.perf_counter() - t0)   # (compiling or loading the kernel, packing)
    est = Estimate.empty(n_bins)
    mean_est = Estimate.empty(1)   # the batch means of the values' mean (target_scope "mean")
    batches = 0
    counters = None
    while True:
        nb = min(max_round, max(shape.first_round, batches // 4))
        if budget.max_photons is not None:
            nb = min(nb, max(1, (budget.max_photons - batches * per_batch) // per_batch))
        nb = max(nb, 2 - batches)   # an error bar needs two batches, whatever the budget
        values, cnt = run_round(batches, nb)
        est.add(values)
        if budget.scope == "mean":
            mean_est.add(values[:, :n_stop].mean(axis=1, keepdims=True))
        counters = cnt.sum(axis=0) if counters is None else counters + cnt.sum(axis=0)
        batches += nb
        elapsed = time.perf_counter() - t0
        worst = stop_error(est, mean_est, n_stop, budget.scope)
        if progress is not None:
            progress(batches * per_batch, worst, elapsed)
        if cancel is not None and cancel():
            return est, batches, "cancelled", counters
        if budget.target is not None and batches >= MIN_BATCHES and worst <= budget.target:
            return est, batches, "target_relative_error", counters
        if budget.max_photons is not None and (batches + 1) * per_batch > budget.max_photons:
            return est, batches, "max_photons", counters
        if budget.max_seconds is not None and elapsed >= budget.max_seconds:
            return est, batches, "max_seconds", counters


def _receivers(probe: Probe, refs, observe_spectrum: bool):
    """The probe's receivers as a scene of their own and the tallies a forward query fills: ``(receiver arrays,
    SensorArrays, bins, area of each bin (m², sr for a far field's, 1 for its total), bins the error stop watches)``.
    Bins are the receivers (grid cells or disks), then a surface's triangles, then a far field's directions and the
    total flux leaving."""
    is_grid, centers, normals, radius = probe.is_grid, probe.centers, probe.normals, probe.radius
    grid: Any = probe.grid
    surface: Any = probe.surface
    far: Any = probe.far
    receivers = Scene()
    ids: list[int] = []
    if is_grid:
        uu, vv, nu, nv = grid
        ids = [receivers.add_rect_sensor(centers, uu, vv)]
        n_bins = nu * nv
        area = np.full(n_bins, float(np.linalg.norm(np.cross(uu, vv))) / (nu * nv))
    else:
        ids = [receivers.add_disk_sensor(c, n, radius) for c, n in zip(centers, normals, strict=True)]
        n_bins = len(centers)
        area = np.full(n_bins, math.pi * radius * radius)
    receivers.commit()
    ra = receivers.arrays()
    bin0 = np.full(max(ids) + 1 if ids else 0, -1, np.int64)
    snu = np.ones(len(bin0), np.int64)
    snv = np.ones(len(bin0), np.int64)
    if is_grid:
        bin0[ids[0]] = 0
        snu[ids[0]], snv[ids[0]] = grid[2], grid[3]
    else:
        bin0[ids] = np.arange(len(ids))
    ref = np.zeros((len(bin0), 3))
    if refs is not None:
        ref[ids] = refs[:len(ids)]
    observe_stokes = refs is not None
    n_stop = n_bins   # the error stop: the receivers, or the triangles where there are none
    surf = np.empty(0, np.int64)
    if surface is not None:
        surf_map, surf_area = surface
        surf = np.where(surf_map >= 0, surf_map + n_bins, -1).astype(np.int64)
        n_bins += len(surf_area)
        area = np.concatenate([area, surf_area])
        n_stop = n_stop or n_bins
    far_row = np.empty(0, np.float64)
    if far is not None:
        far_params, far_omega = far
        far_row = np.array([n_bins, *far_params], np.float64)
        n_bins += len(far_omega) + 1
        area = np.concatenate([area, far_omega, [1.0]])   # cd; the last bin, the total leaving, in lm
        n_stop = n_stop or n_bins - 1
    sens = SensorArrays(bin0, snu, snv, np.array([int(observe_spectrum), int(observe_stokes)], np.int64), ref,
                        surf, far_row)
    return ra, sens, n_bins, area, n_stop


def _observed(res: IlluminanceResult, mean: np.ndarray, err: np.ndarray, observe_spectrum: bool,
              observe_stokes: bool) -> None:
    """What the query observed beside lux, from the tallies' rows (``mean``, ``err``: (columns, bins)): the spectrum
    (W/m²/nm per band, the CIE 1931 xy chromaticity) and the Stokes vector with the degree of polarization."""
    if observe_spectrum:
        res.nm = spectra.bin_centres()
        res.spectral_irradiance = mean[3:].T / spectra.BIN_NM
        res.spectral_stderr = err[3:].T / spectra.BIN_NM
        x, y, z = mean[1], mean[0] / spectra.KM, mean[2]
        total = x + y + z
        with np.errstate(divide="ignore", invalid="ignore"):
            res.cie_xy = np.where(total[:, None] > 0, np.stack([x, y], axis=1) / total[:, None], np.nan)
    if observe_stokes:
        res.stokes = np.concatenate([mean[:1], mean[-3:]]).T
        res.stokes_stderr = np.concatenate([err[:1], err[-3:]]).T
        with np.errstate(divide="ignore", invalid="ignore"):
            res.dop = np.where(mean[0] > 0, np.sqrt((mean[-3:] ** 2).sum(axis=0)) / mean[0], np.nan)


def forward(sim, probe: Probe, budget: Budget, seed: int, effects: list[str], progress, cancel, t0: float,
            observe_spectrum: bool, refs, backend: QueryBackend) -> IlluminanceResult:
    """Photons from the sources into the probe's receivers (and its surface and far-field tallies), round by round
    (`loop`): the raw bins, lx (cd and lm for a far field), with their standard errors."""
    observe_stokes = refs is not None
    ra, sens, n_bins, area, n_stop = _receivers(probe, refs, observe_spectrum)
    n_cols = tally_columns(observe_spectrum, observe_stokes)
    if n_bins * n_cols > MAX_SPECTRAL_TALLIES:
        what = " and ".join(o for o, on in (("the spectrum", observe_spectrum), ("Stokes", observe_stokes)) if on)
        raise SimulationError(f"observing {what} of {n_bins} cells needs {n_bins * n_cols} tallies per "
                              f"batch (at most {MAX_SPECTRAL_TALLIES}): use at most "
                              f"{MAX_SPECTRAL_TALLIES // n_cols} cells")
    shape = backend.shape
    per_batch = shape.forward_photons
    if budget.max_photons is not None:
        per_batch = int(min(shape.forward_photons, max(1, budget.max_photons // (4 * shape.first_round))))
    state = photon_state(effects)
    kernel_id = ("forward", state)
    scene, query = sim.snapshot(state), Shipment((ra, sens, n_bins, seed))
    compile_s = warm(kernel_id, scene, query, backend)

    with np.errstate(divide="ignore"):
        per_area = np.tile(np.where(area > 0, 1.0 / area, 0.0), n_cols)   # a degenerate triangle: 0 ± 0

    def run_round(b0, nb):
        flux, cnt = backend.run(kernel_id, scene, query, b0, nb, per_batch)
        return flux * per_area[None, :], cnt

    est, batches, stop, counters = loop(run_round, n_bins * n_cols, per_batch, budget, progress, cancel, t0,
                                              shape,
                                              n_stop)
    cdict = {name: int(c) for name, c in zip(COUNTERS, counters, strict=True)}
    mean, err = est.mean.reshape(n_cols, n_bins), est.stderr.reshape(n_cols, n_bins)
    res = IlluminanceResult(mean[0], err[0], photons=batches * per_batch, seconds=time.perf_counter() - t0,
                            effects=effects, estimator="forward", stop_reason=stop, batches=batches,
                            rejected=cdict["rejected"], counters=cdict, compile_seconds=compile_s)
    _observed(res, mean, err, observe_spectrum, observe_stokes)
    return res


def backward(sim, probe: Probe, budget: Budget, seed: int, effects: list[str], progress, cancel, t0: float,
             backend: QueryBackend) -> IlluminanceResult:
    """Paths from uniform points of each receiver patch, with next-event estimation (`tracer.transport.backward`),
    round by round: the receivers' lx and standard errors."""
    is_grid, centers, normals, radius = probe.is_grid, probe.centers, probe.normals, probe.radius
    grid: Any = probe.grid
    if is_grid:
        uu, vv, nu, nv = grid
        k = nu * nv
        jj, ii = np.divmod(np.arange(k), nu)
        o = centers[None, :] + (ii / nu)[:, None] * uu[None, :] + (jj / nv)[:, None] * vv[None, :]
        q = QueryArrays(np.ones(k, np.int64), o, np.tile(uu / nu, (k, 1)), np.tile(vv / nv, (k, 1)),
                        np.tile(normals, (k, 1)))
    else:
        q = disk_queries(centers, normals, radius)
        k = len(centers)
    shape = backend.shape
    paths = shape.backward_paths
    per_batch = paths * k
    if budget.max_photons is not None:
        paths = int(min(shape.backward_paths, max(1, budget.max_photons // (4 * shape.first_round * k))))
        per_batch = paths * k
    scene, query = sim.snapshot("backward"), Shipment((q, seed))
    compile_s = warm(("backward",), scene, query, backend)

    def run_round(b0, nb):
        return backend.run(("backward",), scene, query, b0, nb, paths)

    est, batches, stop, counters = loop(run_round, k, per_batch, budget, progress, cancel, t0, shape)
    cdict = {"rejected": int(counters[0]), "truncated": int(counters[1])}
    return IlluminanceResult(est.mean, est.stderr, photons=batches * per_batch, seconds=time.perf_counter() - t0,
                             effects=effects, estimator="backward", stop_reason=stop, batches=batches,
                             rejected=cdict["rejected"], counters=cdict, compile_seconds=compile_s)


@dataclass
class ViewBins(IlluminanceResult):
    """The raw bins of views (`tracer.transport.radiance`): `lux` and `stderr` hold each view's luminance (cd/m²)
    and its standard error; through_specular (k,): the share of each view's paths whose view ray went on through a
    specular surface before any diffuse one."""

    through_specular: np.ndarray | None = None
    light_traced: bool = False   # light tracing ran beside the paths from the eye (`tracer.transport.radiance`)
    area_pilot: dict | None = None   # `area_light_pilot`'s finding, where it ran


VIEW_PATHS = 4096   # paths per batch over all the views together, at least one per view (a camera: one a pixel)
MIN_LIGHT_PATHS = 1024   # light paths per batch at least, where light tracing runs (`tracer.transport.radiance`)
VIEW_EFFECTS = ("lambertian", "specular", "fresnel")   # what paths from the eye follow (`tracer.transport.radiance`)
MIN_AREA_JOINS = 1e-4   # joins a pilot photon of the area lights must average for them to be traced
AREA_RAY_SHARE = 0.5    # their photons cast this many rays per ray of the paths from the eye at least ...
AREA_SHARE_FULL = 0.1   # ... where this share of the light seen comes by light tracing (less: fewer in proportion)
AREA_MAX_RAYS = 4.0     # and at most this many, however much of the light it carries
PILOT_SEED = 0x5EED_A4EA   # the pilot's seed is the query's plus this: its random numbers are none of the query's


def area_light_pilot(scene: Shipment, views, emit, lights, effects, photons: int, paths: int, width: int, seed: int,
                     backend: QueryBackend, others_traced: bool) -> tuple[dict | None, Any]:
    """Whether, and with how many photons a batch, light tracing from the area lights runs beside this query's paths
    from the eye (`tracer.transport.radiance`, "Light tracing"). Two batches of `photons` photons from the area
    lights alone (on a seed of their own) give light tracing's part of the light the views see; two batches of the
    query's paths from the eye alone (`paths` a view) give theirs, and count the paths they found that light tracing
    would take (they meet the emitter after a specular vertex: counter ``left_to_light_tracing``). The area lights
    are traced where their photons had diffuse vertices joined to the views (at least `MIN_AREA_JOINS` a photon;
    behind a light guide's top face none can be), more joins a ray than the paths from the eye had finds a ray.
    Their photons then cast rays in proportion to the light each strategy carries, share / (1 − share) per ray of
    the paths from the eye, up to `AREA_MAX_RAYS` (an LED behind a pane, whose light only light tracing finds), and
    at least `AREA_RAY_SHARE` where the share is `AREA_SHARE_FULL` or more (fewer photons would leave a view that
    needs them with joins too rare for its error bar to see), fewer in proportion below (a guide whose frame alone is
    lit so gives light tracing little). Paths from the eye find all of an area light's light anyway, so the choice
    moves the error bar, not the mean. Counted in rays, not seconds: the same seed gives the same answer.

    Returns (None, None) where there is nothing to decide (no area light, or no specular surface); else ({"photons",
    "joined", "eye_finds", "share", "traced", "per_batch"}, the eye batches' (values, counters) where they are the
    query's own batches 0 and 1, else None). They are reused where no light is traced at all (`others_traced`
    False: no other light is traced anyway), the area lights included: the query's batches are then paths from the
    eye alone, as these are. Where light tracing is chosen they are dropped: paths from the eye alone read, behind
    a pane, 0 in almost every batch and a spike in a rare one, unbiased but no start for an estimate.)"""
    trial = light_paths(lights, effects, photons, width, area=True, others=False)
    if int(trial.photons[0]) == 0:
        return None, None
    pilot_seed = (seed + PILOT_SEED) % 2 ** 63
    k = len(views.kind)
    light, counters = backend.run(("radiance",), scene, Shipment((views, emit, trial, pilot_seed)), 0, 2, 0)
    reuse = not others_traced
    counting = trial._replace(photons=np.zeros(1, np.int64))   # no photons: the eye paths count, and keep, the finds
    eye = backend.run(("radiance",), scene, Shipment((views, emit, counting, seed if reuse else pilot_seed)), 0, 2,
                      paths)
    by_light, by_eye = float(np.sum(light[:, :k])), float(np.sum(eye[0][:, :k]))
    share = by_light / (by_light + by_eye) if by_light > 0.0 else 0.0
    sent, joined = int(counters[:, C_LIGHT_PATHS].sum()), int(counters[:, C_LIGHT_SPLATS].sum())
    light_rays = max(int(counters[:, C_LIGHT_RAYS].sum()), 1)
    view_rays, finds = int(eye[1][:, C_VIEW_RAYS].sum()), int(eye[1][:, C_LEFT].sum())
    traced = joined > 0 and joined >= MIN_AREA_JOINS * sent and joined * view_rays > finds * light_rays
    ratio = AREA_MAX_RAYS if share >= 1.0 else min(AREA_MAX_RAYS, share / (1.0 - share))
    ratio = max(ratio, AREA_RAY_SHARE * min(1.0, share / AREA_SHARE_FULL))
    per_batch = max(1, int(photons * ratio * view_rays / light_rays)) if traced else 0
    return ({"photons": sent, "joined": joined, "eye_finds": finds, "share": share, "traced": traced,
             "per_batch": per_batch}, eye if reuse and not traced else None)


def radiance(sim, probe: Probe, budget: Budget, seed: int, estimator: str, effects: list[str], progress, cancel,
             backend: QueryBackend) -> ViewBins:
    """Paths from the eye of each of the probe's views (`Probe.view`), round by round: their luminance (cd/m²) and
    standard errors, with the cost of tighter errors and the backend. Only "auto" or "backward" answers, and only
    scenes whose effects are in `VIEW_EFFECTS` (`SimulationError` otherwise). The kernel has no GPU variant: on a
    card's backend it runs on this process's threads, and the answer's backend says so."""
    if estimator not in ("auto", "backward"):
        raise SimulationError(f"a luminance or camera sensor is answered by paths from the eye: estimator must be "
                              f"'auto' or 'backward', got {estimator!r}")
    beyond = sorted(set(effects) - set(VIEW_EFFECTS))
    if beyond:
        raise SimulationError(f"the luminance estimator follows {list(VIEW_EFFECTS)} only; this scene (or "
                              f"force_effects) needs {beyond}")
    effects = [e for e in effects if e in VIEW_EFFECTS]
    t0 = time.perf_counter()
    views: Any = probe.view
    k = len(views.kind)
    shape = backend.shape
    if getattr(backend.backend, "name", "") not in ("in-process", "dask"):
        backend.fallback = "ran on the CPU because the luminance kernel has no GPU variant"
        shape = CPU_SHAPE
    paths = int(min(shape.backward_paths, max(1, -(-VIEW_PATHS // k))))
    if budget.max_photons is not None:
        paths = int(min(paths, max(1, budget.max_photons // (4 * shape.first_round * k))))
    per_batch = paths * k
    emit = emitters(sim.light_bodies, len(sim.snapshot("backward").parts[1].kind), sim.scene)
    shape_2d = (probe.keep or {}).get("shape")
    width = int(shape_2d[1]) if shape_2d is not None and int(views.kind[0]) == PIXEL else 0
    lights, scene = sim.snapshot("backward").parts[2], sim.snapshot("backward")
    photons = max(per_batch, MIN_LIGHT_PATHS)
    others = light_paths(lights, effects, photons, width)   # traced whatever the pilot finds of the area lights
    others_traced = int(others.photons[0]) > 0
    compile_s = warm(("radiance",), scene, Shipment((views, emit, no_light_paths(len(others.cdf)), seed)), backend)
    pilot, start = area_light_pilot(scene, views, emit, lights, effects, photons, paths, width, seed, backend,
                                    others_traced)
    traced = others
    if pilot is not None and pilot["traced"]:
        traced = light_paths(lights, effects, photons, width, area=True)
        if not others_traced:   # the area lights alone: as many photons as the pilot found they pay for
            traced = traced._replace(photons=np.array([pilot["per_batch"]], np.int64))
    query = Shipment((views, emit, traced, seed))

    def run_round(b0, nb):
        if start is None or b0 > 0:
            return backend.run(("radiance",), scene, query, b0, nb, paths)
        rest = backend.run(("radiance",), scene, query, 2, nb - 2, paths) if nb > 2 else None
        if rest is None:   # the pilot's eye batches are batches 0 and 1
            return start
        return np.concatenate([start[0], rest[0]]), np.concatenate([start[1], rest[1]])

    est, batches, stop, counters = loop(run_round, 2 * k, per_batch, budget, progress, cancel, t0, shape, k)
    cdict = {name: int(c) for name, c in zip(RADIANCE_COUNTERS, counters, strict=True)}
    res = ViewBins(est.mean[:k], est.stderr[:k], photons=batches * per_batch, seconds=time.perf_counter() - t0,
                   effects=effects, estimator="backward", stop_reason=stop, batches=batches,
                   rejected=cdict["rejected"], counters=cdict, compile_seconds=compile_s,
                   through_specular=est.mean[k:], light_traced=int(traced.photons[0]) > 0, area_pilot=pilot)
    res.cost = cost_of(res.lux, res.stderr, res.photons, res.seconds - res.compile_seconds)
    res.backend = backend.describe()
    return res


def compile_seconds() -> dict[str, float]:
    """Seconds each kernel variant took to compile or load, this process: {"forward/white": s, "backward": s}."""
    return {"/".join(variant): s for variant, s in _COMPILE_SECONDS.items()}
