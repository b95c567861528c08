"""Packing a density element: the extraction pattern of a light guide found by feedback on the simulated lit face
(issue 41; LightTools calls it mesh feedback optimisation).

Start from a density element (`tracer.elements.microstructure`, layout ``density``) on a part's face and a grid
sensor of cells over the lit face (its cells are the meters: illuminance, lx; or, as a display is judged, the
luminance a viewer in front of each cell sees, cd/m², `Reading`). Each iteration

1. prepares the element's inner model from the current fill map and puts it onto the part
   (`tracer.Scene.set_element`, then `commit`): only that instance's element changes, the top level and every other
   bottom level stay (`PackIteration.update_seconds` against a full rebuild, measured by the caller);
2. measures the grid (a fresh seed each time): with forward photons, or with luminance meters and paths from the
   eye;
3. takes the log-deviation of each cell from the mean, ``d = ln(mean / E)``, shrinks it by its own measurement
   error (soft threshold at `NOISE_SIGMAS` standard errors: a deviation the noise could make changes nothing),
   interpolates it over the support (the cells' centres projected onto the sensor plane, bilinear, clamped at the
   edges; each map cell the mean of 5 x 5 samples) and multiplies the fill by ``exp(damping d)``, all of it scaled
   down where a cell would pass ``max_fill`` (a cell that cannot rise pulls the others down to it), kept in
   ``[0, max_fill]`` on a lattice of the given pitch (the minimum pitch between features).

It stops on the target (the figure, min/max or min/mean, at least `target`) only once a second measurement with a
fresh seed confirms it (issue 53: the best of several noisy readings is biased upwards, so a pack that stopped on its
own reading stopped on luck as often as on the pattern): where the confirmation falls short, the iteration's two
readings, pooled, correct the map and the pack goes on. It also stops on a budget (iterations, seconds), on a
cancel, or when no cell deviates beyond its error although the photons are at their maximum. The photons rise as
the map converges so that it never chases noise: where the largest deviation is within `RAISE_SIGMAS` of the
typical error, the next iteration takes four times the photons (half the error), up to ``max_photons``.

The answer keeps every iteration (figure ± error, photons, seconds, the confirmation where one was measured) and the
map it measured; the chosen pattern is the confirmed one, else the one measured best by its figure less one standard
error (an iteration with a confirmation by the two readings pooled).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tracer.elements import features as fx
from tracer.elements.checks import ElementError
from tracer.elements.microstructure import Microstructure, prepare

FIGURES = ("min_max", "min_mean")
QUANTITIES = ("illuminance", "luminance")
NOISE_SIGMAS = 2.0     # a cell's deviation within this many standard errors is noise: no change
RAISE_SIGMAS = 4.0     # the largest deviation within this many typical errors: four times the photons next
MAX_STEP = math.log(2.0)   # the largest log-change of a cell's target per iteration (before damping)
FLOOR = 1e-3           # a fill never falls below this where the update would raise it (0 stays 0 otherwise)
SUB = 5                # samples per side of a map cell when the correction is interpolated onto it


class PackError(ElementError):
    """A pack that cannot run: a target out of range, an element that is not a density map, a dark face."""


@dataclass(frozen=True)
class Reading:
    """How a pack reads the lit face at its grid's cells: ``illuminance`` (lx: the grid sensor itself, forward
    photons) or ``luminance`` (cd/m²: what a viewer sees, a meter `distance` m behind each cell's centre, on the
    grid's back side, looking through it along its front normal u × v with a cone of `aperture_deg` degrees; paths
    from the eye, `tracer.sensors.luminance.meters`)."""

    quantity: str = "illuminance"
    distance: float = 0.5
    aperture_deg: float = 1.0

    def check(self) -> None:
        """`PackError` naming the field that cannot be read."""
        if self.quantity not in QUANTITIES:
            raise PackError(f"quantity must be one of {list(QUANTITIES)}, got {self.quantity!r}")
        for name, x, hi in (("distance", self.distance, 1e3), ("aperture_deg", self.aperture_deg, 180.0)):
            if isinstance(x, bool) or not isinstance(x, int | float) or not 0.0 < x <= hi:
                raise PackError(f"{name} must be a number in (0, {hi:g}], got {x!r}")

    @property
    def unit(self) -> str:
        return "lx" if self.quantity == "illuminance" else "cd/m²"


def cell_centres(sensor: dict) -> tuple[np.ndarray, np.ndarray]:
    """The centres of a grid sensor's cells, (nv * nu, 3) world m row by row along v (its readings' order), and
    its unit front normal u × v."""
    o, u, v = (np.asarray(sensor[k], float) for k in ("origin", "u", "v"))
    s = (np.arange(int(sensor["nu"])) + 0.5) / int(sensor["nu"])
    t = (np.arange(int(sensor["nv"])) + 0.5) / int(sensor["nv"])
    centres = o + t[:, None, None] * v + s[None, :, None] * u
    front = np.cross(u, v)
    return centres.reshape(-1, 3), front / np.linalg.norm(front)


def read(sim: Any, sensor: dict, reading: Reading, photons: int, seed: int, report: Callable | None,
         cancel: Callable[[], bool] | None) -> tuple[np.ndarray, np.ndarray, int]:
    """The lit face read at the grid's cells: (values (nv, nu) in `reading.unit`, their standard errors, photons
    or paths traced)."""
    if reading.quantity == "illuminance":
        res = sim.run(sensor, max_photons=photons, seed=seed, estimator="forward", progress=report, cancel=cancel)
        return np.asarray(res.lux, float), np.asarray(res.stderr, float), int(res.photons)
    from tracer.sensors.luminance import meters

    centres, front = cell_centres(sensor)
    res = meters(sim, centres - reading.distance * front, np.tile(front, (len(centres), 1)), reading.aperture_deg,
                 max_photons=photons, seed=seed, estimator="backward", progress=report, cancel=cancel)
    shape = (int(sensor["nv"]), int(sensor["nu"]))
    return (np.asarray(res.luminance, float).reshape(shape), np.asarray(res.stderr, float).reshape(shape),
            int(res.photons))


@dataclass
class PackIteration:
    """One iteration: the fill it measured, its figure with the standard error, the photons, the seconds."""

    iteration: int
    fill: list[list[float]]
    features: int
    photons: int
    uniformity: float
    stderr: float
    min_mean: float
    lux: list[list[float]]          # the readings: lx, or cd/m² where the pack reads luminance (`Reading`)
    lux_stderr: list[list[float]]
    update_seconds: float      # prepare + set_element + commit + a new Simulation
    measure_seconds: float
    seconds: float             # the iteration's whole time
    #: where the reading reached the target: a second measurement with a fresh seed, {"uniformity", "stderr",
    #: "photons", "seed", "confirmed"} (confirmed: it reached the target too)
    confirmation: dict[str, Any] | None = None

    def public(self) -> dict[str, Any]:
        """What a history lists (no maps)."""
        return {"iteration": self.iteration, "uniformity": self.uniformity, "stderr": self.stderr,
                "min_mean": self.min_mean, "photons": self.photons, "features": self.features,
                "update_seconds": self.update_seconds, "measure_seconds": self.measure_seconds,
                "seconds": self.seconds, "confirmation": self.confirmation}

    def pooled(self) -> tuple[float, float]:
        """(figure, standard error) of the iteration: its reading, or with a confirmation both pooled (the mean of two
        independent readings, its error half their errors' root sum of squares)."""
        c = self.confirmation
        if c is None:
            return self.uniformity, self.stderr
        return 0.5 * (self.uniformity + c["uniformity"]), 0.5 * math.hypot(self.stderr, c["stderr"])


@dataclass
class PackResult:
    """The pack's answer: the chosen model (its iteration `best`), why it stopped, every iteration."""

    element: Microstructure
    best: int
    stopped: str               # "target", "iterations", "seconds", "converged", "cancelled"
    history: list[PackIteration] = field(default_factory=list)
    figure: str = "min_max"
    target: float = 0.8
    seconds: float = 0.0
    reading: Reading = Reading()


def confirm(sim: Any, sensor: dict, measured: PackIteration, photons: int, seed: int, figure: str, target: float,
            report: Callable, cancel: Callable[[], bool] | None, reading: Reading = Reading()
            ) -> tuple[np.ndarray, np.ndarray] | None:
    """Measure iteration `measured`'s pattern again with the fresh `seed` (its reading reached `target`) and keep the
    reading in ``measured.confirmation``; answers the two readings pooled (lux, stderr), or None where it was
    cancelled (nothing kept)."""
    t0 = time.perf_counter()
    lux, err, traced = read(sim, sensor, reading, photons, seed, report, cancel)
    if cancel is not None and cancel():
        return None
    u, s, _ = figure_of(lux, err, figure)
    measured.confirmation = {"uniformity": u, "stderr": s, "photons": traced, "seed": seed,
                             "confirmed": bool(u >= target)}
    measured.measure_seconds += time.perf_counter() - t0
    measured.seconds += time.perf_counter() - t0
    return (0.5 * (np.asarray(measured.lux) + lux), 0.5 * np.hypot(np.asarray(measured.lux_stderr), err))


def confirmation_seed(seed: int, iteration: int) -> int:
    """The photon seed of iteration `iteration`'s confirmation: none of the pack's own measurements takes it (they
    take ``seed * 1009 + iteration``)."""
    return int(seed) * 1009 + 500_000 + int(iteration)


def check(start: Microstructure, target: Any, figure: Any = "min_max", damping: Any = 0.7, max_fill: Any = 1.0,
          pitch_mm: Any = None) -> None:
    """Refuse a pack that cannot run, naming the field: a target outside (0, 1], an unknown figure, a damping
    outside (0, 1], a max_fill outside (0, 1], an element that is not a density layout."""
    if start.layout != fx.DENSITY:
        kind = start.body.get("layout", {}).get("type")
        raise PackError(f"element: its layout is {kind!r}; only a 'density' layout (a fill map) can be packed")
    for name, x in (("target", target), ("damping", damping), ("max_fill", max_fill)):
        if isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(x) or not 0.0 < x <= 1.0:
            raise PackError(f"{name} must be a number in (0, 1], got {x!r}"
                            + (": a uniformity is a ratio of the smallest value to the largest (or the mean)"
                               if name == "target" else ""))
    if figure not in FIGURES:
        raise PackError(f"figure must be one of {list(FIGURES)}, got {figure!r}")
    if pitch_mm is not None:   # a pitch smaller than the feature is refused, naming layout.pitch_mm
        prepare(density_body(start.body, np.asarray(start.body["layout"]["fill"]), pitch_mm))


def density_body(body: dict, fill: np.ndarray, pitch_mm: float | None = None) -> dict:
    """`body` (a density element's) with the fill map `fill` (and the lattice pitch where given)."""
    layout = {**body["layout"], "fill": [[float(x) for x in row] for row in np.asarray(fill, float)]}
    if pitch_mm is not None:
        layout["pitch_mm"] = pitch_mm
    return {**body, "layout": layout}


def figure_of(lux: np.ndarray, err: np.ndarray, figure: str) -> tuple[float, float, float]:
    """(figure, its standard error, min/mean) of a measured map (`tracer.photometry.glare.uniformity`)."""
    from tracer.photometry.glare import uniformity

    u = uniformity(lux, err)
    return float(u[figure]), float(u[f"{figure}_stderr"]), float(u["min_mean"])


def correction(lux: np.ndarray, err: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Per cell, the log-change toward the mean that the measurement supports: ``ln(mean/E)`` soft-thresholded at
    `NOISE_SIGMAS` of its error and capped at `MAX_STEP`; with the largest raw deviation and the typical (median)
    relative error."""
    mean = float(lux.mean())
    safe = np.maximum(lux, mean * 1e-3)
    d = np.clip(np.log(mean / safe), -MAX_STEP, MAX_STEP)
    sig = np.where(lux > 0, err / safe, 1.0)
    shrunk = np.sign(d) * np.maximum(np.abs(d) - NOISE_SIGMAS * sig, 0.0)
    return shrunk, float(np.abs(d).max()), float(np.median(sig))


def on_support(d: np.ndarray, sensor: dict, shape: tuple[int, int], layout: dict, origin: np.ndarray,
               du: np.ndarray, dv: np.ndarray) -> np.ndarray:
    """The sensor's per-cell correction `d` (nv, nu) carried onto the fill map's cells (rows along v, columns
    along u): each map cell's samples projected onto the sensor plane, the cell-centre values interpolated
    bilinearly (clamped at the edges), averaged."""
    rows, cols = shape
    (u0, v0), (su, sv) = layout["origin_mm"], layout["size_mm"]
    k = (np.arange(SUB) + 0.5) / SUB
    uu = u0 + (np.arange(cols)[:, None] + k[None, :]).ravel() * su / cols        # (cols*SUB,)
    vv = v0 + (np.arange(rows)[:, None] + k[None, :]).ravel() * sv / rows        # (rows*SUB,)
    p = origin + uu[None, :, None] * du + vv[:, None, None] * dv                 # (rows*SUB, cols*SUB, 3)
    o, a, b = (np.asarray(sensor[x], float) for x in ("origin", "u", "v"))
    m = np.linalg.pinv(np.stack([a, b], axis=1))                                 # (2, 3): least squares s, t
    st = (p - o) @ m.T
    nv_, nu_ = d.shape
    x = np.clip(st[..., 0] * nu_ - 0.5, 0.0, nu_ - 1)
    y = np.clip(st[..., 1] * nv_ - 0.5, 0.0, nv_ - 1)
    i0 = np.minimum(np.floor(x).astype(int), max(nu_ - 2, 0))
    j0 = np.minimum(np.floor(y).astype(int), max(nv_ - 2, 0))
    i1, j1 = np.minimum(i0 + 1, nu_ - 1), np.minimum(j0 + 1, nv_ - 1)
    fx_, fy = x - i0, y - j0
    val = ((1 - fx_) * (1 - fy) * d[j0, i0] + fx_ * (1 - fy) * d[j0, i1] + (1 - fx_) * fy * d[j1, i0]
           + fx_ * fy * d[j1, i1])
    return val.reshape(rows, SUB, cols, SUB).mean(axis=(1, 3))


def update(fill: np.ndarray, d: np.ndarray, damping: float, max_fill: float) -> np.ndarray:
    """The damped multiplicative step ``fill exp(damping d)``, scaled down as a whole where a cell would pass
    `max_fill` (a cell that cannot rise pulls the others down to it instead), kept in [0, max_fill]; a cell at 0
    that should rise starts from `FLOOR`."""
    base = np.where((fill <= 0.0) & (d > 0.0), FLOOR, fill)
    new = base * np.exp(damping * d)
    top = float(new.max())
    if top > max_fill:
        new *= max_fill / top
    return np.clip(new, 0.0, max_fill)


@dataclass
class _Run:
    """The state a pack carries from one iteration to the next (so its steps can be helpers)."""

    photons: int                # the next measurement's photons
    total: int = 0              # photons traced so far, confirmations included
    stopped: str = "iterations"
    history: list[PackIteration] = field(default_factory=list)
    models: list[Microstructure] = field(default_factory=list)


def _check_run(start: Microstructure, sensor: dict, target: float, figure: str, damping: float, max_fill: float,
               pitch_mm: float | None, photons: int, max_photons: int, max_iterations: int, reading: Reading) -> None:
    """Refuse a pack before it changes the scene: `check`'s fields, the reading, then the sensor, then the budgets."""
    check(start, target, figure, damping, max_fill, pitch_mm)
    reading.check()
    if sensor.get("type") != "grid":
        raise PackError(f"sensor: a pack measures a grid of cells over the lit face, got a {sensor.get('type')!r} "
                        f"sensor")
    for name, x, lo in (("photons", photons, 1000), ("max_photons", max_photons, photons),
                        ("max_iterations", max_iterations, 1)):
        if isinstance(x, bool) or not isinstance(x, int) or x < lo:
            raise PackError(f"{name} must be an integer >= {lo}, got {x!r}")


def _place(scene: Any, instance: int, start: Microstructure, fill: np.ndarray, pitch_mm: float | None, it: int,
           simulation: Callable[[Any], Any], assign: dict[str, Any]) -> tuple[Microstructure, Any, Any]:
    """Put iteration `it`'s model onto the part and commit, so only that element changes: (model, simulation,
    placement); the first iteration reuses `start` unless a pitch must be applied."""
    model = prepare(density_body(start.body, fill, pitch_mm)) if (it or pitch_mm is not None) else start
    scene.set_element(instance, model, **assign)
    scene.commit()
    sim = simulation(scene)
    placed = scene.element_of(instance, assign.get("key", 0))
    if placed is None:   # pragma: no cover - set_element raised otherwise
        raise PackError("the element did not go onto the part")
    return model, sim, placed


def _reporter(progress: Callable[[dict[str, Any]], None] | None, history: list[PackIteration], it: int, done: int,
              t_start: float) -> Callable[[int, float, float], None]:
    """The photon-round callback of iteration `it` (`done` photons traced before it): it reads the last measured
    iteration from `history` when called, so a confirmation reports the iteration it confirms."""
    def report(p: int, worst: float, seconds: float) -> None:
        if progress is not None:
            last = history[-1] if history else None
            progress({"iteration": it, "photons": done + int(p), "measured": last and last.iteration,
                      "uniformity": last and last.uniformity, "stderr": last and last.stderr,
                      "seconds": time.perf_counter() - t_start})

    return report


def _target_reached(run: _Run, sim: Any, sensor: dict, it: int, seed: int, figure: str, target: float,
                    max_photons: int, report: Callable, cancel: Callable[[], bool] | None, reading: Reading
                    ) -> tuple[np.ndarray, np.ndarray] | None:
    """Confirm a reading at the target with a fresh seed (issue 53): None where the pack stops (`run.stopped` says
    why), else the two readings pooled to correct the map with, and four times the photons next (near the target
    the noise decides: halve it)."""
    pooled = confirm(sim, sensor, run.history[-1], run.photons, confirmation_seed(seed, it), figure, target, report,
                     cancel, reading)
    again = run.history[-1].confirmation
    if pooled is None or again is None:
        run.stopped = "cancelled"
        return None
    run.total += int(again["photons"])
    if again["confirmed"]:
        run.stopped = "target"
        return None
    run.photons = min(4 * run.photons, int(max_photons))
    return pooled


def _next_correction(run: _Run, lux: np.ndarray, err: np.ndarray, max_photons: int, t_start: float,
                     max_seconds: float, last: bool) -> np.ndarray | None:
    """The correction to apply to the map, or None where the pack stops (converged, out of seconds, or the `last`
    iteration); raises the photons where the deviations are within the noise, so the map never chases it."""
    d, worst, typical = correction(lux, err)
    if not np.any(d) and run.photons >= max_photons:
        run.stopped = "converged"
        return None
    if worst < RAISE_SIGMAS * typical or not np.any(d):
        run.photons = min(4 * run.photons, int(max_photons))
    if time.perf_counter() - t_start >= max_seconds:
        run.stopped = "seconds"
        return None
    if last:
        return None
    return d


def _best(run: _Run) -> int:
    """The chosen iteration: the confirmed one, else the best figure less one standard error (pooled readings)."""
    history = run.history
    best = max(range(len(history)), key=lambda k: history[k].pooled()[0] - history[k].pooled()[1])
    if run.stopped == "target":
        best = len(history) - 1
    return best


def pack(scene: Any, instance: int, start: Microstructure, sensor: dict, simulation: Callable[[Any], Any], *,
         assign: dict[str, Any], target: float = 0.8, figure: str = "min_max", photons: int = 100_000,
         max_photons: int = 1_600_000, max_iterations: int = 10, max_seconds: float = 600.0, damping: float = 0.7,
         max_fill: float = 1.0, pitch_mm: float | None = None, seed: int = 1, reading: Reading = Reading(),
         progress: Callable[[dict[str, Any]], None] | None = None,
         cancel: Callable[[], bool] | None = None) -> PackResult:
    """Pack `start`'s fill map on `instance` of `scene` (a `tracer.Scene` the caller owns: the pack changes its element)
    against the grid sensor body `sensor` (world units); `simulation(scene)` makes a `tracer.simulate.Simulation` of the
    committed scene; `assign` holds `Scene.set_element`'s keywords (facing or faces, mm_per_unit, and the element's key
    where the part carries several); `reading` says what the grid's cells read (illuminance, or luminance as a viewer
    sees it). See the module docstring. `progress(state)` gets ``{"iteration", "photons", "measured", "uniformity",
    "stderr", "seconds"}`` between photon rounds and after each iteration: "iteration" is the one running, "uniformity"
    ± "stderr" that of iteration "measured" (the one before while an iteration measures, None before the first has);
    `cancel()` is polled between rounds.

    Raises
    ------
    PackError
        See `check`; a sensor that is not a grid; no light on the grid in the first measurement.
    """
    _check_run(start, sensor, target, figure, damping, max_fill, pitch_mm, photons, max_photons, max_iterations,
               reading)
    t_start = time.perf_counter()
    fill = np.asarray(start.body["layout"]["fill"], float)
    layout = start.body["layout"]
    run = _Run(photons=int(photons))
    history = run.history
    for it in range(max_iterations):
        t0 = time.perf_counter()
        model, sim, placed = _place(scene, instance, start, fill, pitch_mm, it, simulation, assign)
        t1 = time.perf_counter()
        report = _reporter(progress, history, it, run.total, t_start)
        lux, err, traced = read(sim, sensor, reading, run.photons, int(seed) * 1009 + it, report, cancel)
        t2 = time.perf_counter()
        run.total += traced
        if cancel is not None and cancel() and history:
            run.stopped = "cancelled"    # a partial measurement is not taken
            break
        if not lux.max() > 0:
            raise PackError(f"sensor: no light reaches the grid over the face with the starting pattern (every cell "
                            f"read 0 {reading.unit}): check the lights and that the grid faces the lit face")
        u, s, u0 = figure_of(lux, err, figure)
        run.models.append(model)
        history.append(PackIteration(it, fill.tolist(), int(model.features or 0), traced, u, s, u0,
                                     lux.tolist(), err.tolist(), t1 - t0, t2 - t1, time.perf_counter() - t0))
        if progress is not None:
            progress({"iteration": it, "photons": run.total, "measured": it, "uniformity": u, "stderr": s,
                      "seconds": time.perf_counter() - t_start})
        if cancel is not None and cancel():
            run.stopped = "cancelled"
            break
        if u >= target:   # confirmed by a fresh seed, or the two readings pooled correct the map
            pooled = _target_reached(run, sim, sensor, it, seed, figure, target, max_photons, report, cancel,
                                     reading)
            if pooled is None:
                break
            lux, err = pooled
        d = _next_correction(run, lux, err, max_photons, t_start, max_seconds, it + 1 == max_iterations)
        if d is None:
            break
        _, o, du, dv = placed
        fill = update(fill, on_support(d, sensor, fill.shape, layout, o, du, dv), damping, max_fill)
    if not history:
        raise PackError("the pack was cancelled before its first measurement")
    best = _best(run)
    return PackResult(run.models[best], best, run.stopped, history, figure, float(target),
                      time.perf_counter() - t_start, reading)
