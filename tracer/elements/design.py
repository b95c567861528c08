"""A design loop over an element's parameters (issue 53): the feature's height, a prism's apex, the lattice pitch,
a printed dot's reflectance, tuned together with the density map against what the lit face reads.

An engineer names one to three numbers of the element's body (``"feature.height_mm"``, ``"feature.apex_deg"``,
``"layout.pitch_mm"``, ``"material.reflectance"``; a list's entry as ``"layout.pitch_mm[0]"``), each with the values
to try (or ``lo``, ``hi`` and ``steps``), and an objective: a uniformity (``min_max``, ``min_mean``), the ``mean``
reading (on-axis luminance where the grid reads luminance), or the viewing-angle spread ``half_angle`` (degrees: where
the luminance falls to half its on-axis value in a conoscopic view of the grid's centre, `half_angle_of`), raised or,
with ``goal="min"``, lowered (a brightness film narrows the spread, a diffuser widens it). The loop

1. packs the density map at the starting parameters where asked (`tracer.elements.pack`, its own target and
   budget), or keeps the map as it is: the baseline;
2. sweeps every combination of the values (at most `MAX_CANDIDATES`) with that map: each prepared, put onto the
   part and read with the same seed, so that all candidates share their random numbers (common random numbers:
   what differs between two readings is the design, not the draw; `bench/bench_design.py` measures how much
   tighter their differences are than with independent seeds). A combination the element cannot take (a dome
   taller than its radius, a pitch below the feature) is listed as refused, with the reason, and skipped;
3. packs the map again at the best combination, where asked;
4. confirms: the baseline and the result read again with a seed no earlier reading took, the improvement (positive
   where the result is better by the goal) and its standard error (the two readings' errors combined as if
   independent: with shared random numbers the true error of the difference is smaller, so the error bar is an upper
   bound), and whether it exceeds twice that.

The answer keeps every candidate (values, objective ± error, photons, seconds), the packs' histories and the
confirmation; progress is reported after each reading, and a cancel stops the loop at the next reading, keeping the
best candidate measured so far (unconfirmed).
"""

from __future__ import annotations

import itertools
import math
import re
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tracer.elements.checks import ElementError
from tracer.elements.microstructure import Microstructure, prepare
from tracer.elements.pack import FIGURES, PackError, PackResult, Reading, cell_centres, figure_of, pack, read

OBJECTIVES = (*FIGURES, "mean", "half_angle")
GOALS = ("max", "min")
#: the conoscopic view the ``half_angle`` objective reads at the grid's centre: polar angles 0 to 80 degrees in 5-degree
#: rings, 8 azimuths (129 meters; the reading's distance and aperture)
SPREAD_VIEW: dict[str, Any] = {"theta_max_deg": 80.0, "rings": 17, "azimuths": 8}
MAX_PARAMETERS = 3
MAX_CANDIDATES = 64
SWEEP_SEED = 7919           # the sweep's seed is seed * SWEEP_SEED: every candidate reads with it
CONFIRM_SEED = 104_729      # the confirmation's: seed * CONFIRM_SEED + 1, taken by no pack or sweep reading
_PATH = re.compile(r"^(feature|layout|material)\.([a-z_]+)(?:\[(\d)\])?$")


@dataclass(frozen=True)
class Parameter:
    """One number of the element's body to vary: its path (``"feature.height_mm"``, ``"layout.pitch_mm[0]"``) and
    the values to try, in the body's units."""

    name: str
    values: tuple[float, ...]

    @classmethod
    def from_body(cls, body: Any, k: int) -> Parameter:
        """A parameter from its request body ``{"name", "values": [...]}`` or ``{"name", "lo", "hi", "steps"}``;
        `PackError` naming ``parameters[k]`` and its field."""
        where = f"parameters[{k}]"
        if not isinstance(body, dict) or not isinstance(body.get("name"), str):
            raise PackError(f"{where} must be an object with a 'name' (a number of the element's body, e.g. "
                            f"'feature.height_mm') and 'values' or 'lo', 'hi', 'steps'")
        given = set(body) - {"name"}
        if given == {"values"}:
            values = body["values"]
            if not isinstance(values, list) or not 1 <= len(values) <= MAX_CANDIDATES or not all(
                    _finite(x) for x in values):
                raise PackError(f"{where}.values must be a list of 1 to {MAX_CANDIDATES} finite numbers")
            return cls(body["name"], tuple(float(x) for x in values))
        if given == {"lo", "hi", "steps"}:
            lo, hi, steps = body["lo"], body["hi"], body["steps"]
            if not (_finite(lo) and _finite(hi) and lo < hi):
                raise PackError(f"{where}: lo and hi must be finite numbers with lo < hi, got {lo!r} and {hi!r}")
            if isinstance(steps, bool) or not isinstance(steps, int) or not 2 <= steps <= MAX_CANDIDATES:
                raise PackError(f"{where}.steps must be an integer from 2 to {MAX_CANDIDATES}, got {steps!r}")
            return cls(body["name"], tuple(float(x) for x in np.linspace(lo, hi, steps)))
        raise PackError(f"{where} takes 'values', or 'lo', 'hi' and 'steps', beside its 'name'; got "
                        f"{sorted(given)}")

    def read_from(self, body: dict) -> float:
        """The parameter's value in `body`; `PackError` where the body has no number there."""
        parent, key, index = self._locate(body)
        x = parent[key]
        if index is not None:
            if not isinstance(x, list) or index >= len(x):
                raise PackError(f"parameters: {self.name!r}: the element's {key} is {x!r}, with no entry {index}")
            x = x[index]
        elif isinstance(x, list):
            raise PackError(f"parameters: {self.name!r} is a list in this element ({x!r}): name one of its entries, "
                            f"e.g. '{self.name}[0]'")
        if not _finite(x):
            raise PackError(f"parameters: {self.name!r} is not a number in this element ({x!r})")
        return float(x)

    def set_in(self, body: dict, value: float) -> dict:
        """A copy of `body` with the parameter set to `value` (the copies it needs, never `body`'s own)."""
        parent, key, index = self._locate(body)
        group = self.name.split(".")[0]
        new_parent = {**parent}
        if index is None:
            new_parent[key] = value
        else:
            new_parent[key] = [*parent[key]]
            new_parent[key][index] = value
        return {**body, group: new_parent}

    def _locate(self, body: dict) -> tuple[dict, str, int | None]:
        m = _PATH.match(self.name)
        if m is None:
            raise PackError(f"parameters: name {self.name!r} is no number of an element's body; name one as "
                            f"'feature.height_mm', 'layout.pitch_mm', 'material.reflectance' (a list's entry as "
                            f"'layout.pitch_mm[0]')")
        group, key, index = m.group(1), m.group(2), m.group(3)
        parent = body.get(group)
        if not isinstance(parent, dict) or key not in parent:
            raise PackError(f"parameters: this element's body has no {group}.{key} (its {group}: "
                            f"{sorted(parent) if isinstance(parent, dict) else parent!r})"[:300])
        if key in ("fill", "uv_mm", "origin_mm", "size_mm", "seed"):
            raise PackError(f"parameters: {group}.{key} is not a design parameter (the fill map is packed, not "
                            f"swept)")
        return parent, key, None if index is None else int(index)


def _finite(x: Any) -> bool:
    return not isinstance(x, bool) and isinstance(x, int | float) and math.isfinite(x)


@dataclass
class Candidate:
    """One combination of the parameters, as the sweep read it (or refused it)."""

    values: dict[str, float]
    objective: float = math.nan
    stderr: float = math.nan
    photons: int = 0
    seconds: float = 0.0
    refused: str | None = None

    def public(self) -> dict[str, Any]:
        return {"values": self.values, "objective": None if math.isnan(self.objective) else self.objective,
                "stderr": None if math.isnan(self.stderr) else self.stderr, "photons": self.photons,
                "seconds": self.seconds, "refused": self.refused}


@dataclass
class DesignResult:
    """The loop's answer: the chosen element and its parameters, the baseline and the result confirmed on a fresh
    seed, every candidate, the packs' results."""

    element: Microstructure
    values: dict[str, float]
    objective: str
    stopped: str                               # "done", "seconds", "cancelled"
    goal: str = "max"
    candidates: list[Candidate] = field(default_factory=list)
    baseline: dict[str, Any] = field(default_factory=dict)   # values, objective, stderr (the sweep's reading)
    confirmation: dict[str, Any] | None = None
    packs: list[PackResult] = field(default_factory=list)
    seconds: float = 0.0
    reading: Reading = Reading()


def objective_of(values: np.ndarray, err: np.ndarray, objective: str) -> tuple[float, float]:
    """(objective, its standard error) of a read map: a uniformity figure, or the mean reading."""
    if objective == "mean":
        return float(values.mean()), float(math.sqrt(float((err ** 2).sum())) / values.size)
    u, s, _ = figure_of(values, err, objective)
    return u, s


def half_angle_of(simulation: Any, sensor: dict, reading: Reading, photons: int, seed: int,
                  cancel: Callable[[], bool] | None) -> tuple[float, float, int]:
    """The ``half_angle`` objective: the conoscopic view (`SPREAD_VIEW`) of the grid's centre from its back side (where
    a `Reading` of luminance stands), read with `photons` paths from the eye and `seed`, and its half-luminance angle
    (`tracer.sensors.luminance.half_angle`): (degrees, standard error, paths traced). A view that stays above half
    its axis reading reads the view's largest angle with error 0; a view dark on its axis is a `PackError`."""
    from tracer.sensors.luminance import conoscope, half_angle

    centres, front = cell_centres(sensor)
    views, res = conoscope(simulation, centres.mean(axis=0), -front, distance=reading.distance,
                           aperture_deg=reading.aperture_deg, max_photons=photons, seed=seed, estimator="backward",
                           cancel=cancel, **SPREAD_VIEW)
    deg, err, _ = half_angle(views["theta_deg"], views["luminance"], views["stderr"])
    if math.isnan(deg) and not (cancel is not None and cancel()):
        raise PackError("sensor: the grid's centre is dark seen straight on (0 cd/m² on the conoscope's axis): no "
                        "viewing-angle spread to read")
    return deg, err, int(res.photons)


def check(start: Microstructure, parameters: list[Parameter], objective: str, goal: str = "max") -> None:
    """Refuse a design that cannot run, naming the field: an unknown objective or goal, no or too many parameters,
    one named twice or absent from the element, too many combinations."""
    if objective not in OBJECTIVES:
        raise PackError(f"objective must be one of {list(OBJECTIVES)}, got {objective!r}")
    if goal not in GOALS:
        raise PackError(f"goal must be one of {list(GOALS)} (raise or lower the objective), got {goal!r}")
    if not 1 <= len(parameters) <= MAX_PARAMETERS:
        raise PackError(f"parameters: name 1 to {MAX_PARAMETERS} numbers of the element to vary, got "
                        f"{len(parameters)}")
    names = [p.name for p in parameters]
    if len(set(names)) != len(names):
        raise PackError(f"parameters: {names} names one twice")
    for p in parameters:
        p.read_from(start.body)
    count = math.prod(len(p.values) for p in parameters)
    if count > MAX_CANDIDATES:
        raise PackError(f"parameters: {count} combinations, more than {MAX_CANDIDATES} a design sweeps: fewer "
                        f"values or steps")


@dataclass
class _Bench:
    """Where the loop reads a candidate: the part, the grid, how it is read and with how many photons."""

    scene: Any
    instance: int
    sensor: dict
    simulation: Callable[[Any], Any]
    assign: dict[str, Any]
    photons: int
    reading: Reading
    objective: str
    cancel: Callable[[], bool] | None
    goal: str = "max"

    def better(self, a: float, b: float) -> bool:
        """Whether objective `a` is better than `b` by the goal."""
        return a > b if self.goal == "max" else a < b

    def measure(self, model: Microstructure, seed: int) -> tuple[float, float, int] | None:
        """Put `model` onto the part, commit, and read the grid (or, for ``half_angle``, the view of its centre) with
        `seed`: (objective, its standard error, photons); None where a cancel cut the reading short (a partial reading
        is not taken)."""
        self.scene.set_element(self.instance, model, **self.assign)
        self.scene.commit()
        if self.objective == "half_angle":
            got = half_angle_of(self.simulation(self.scene), self.sensor, self.reading, self.photons, seed,
                                self.cancel)
            return None if self.cancel is not None and self.cancel() else got
        values, err, traced = read(self.simulation(self.scene), self.sensor, self.reading, self.photons, seed, None,
                                   self.cancel)
        if self.cancel is not None and self.cancel():
            return None
        if not values.max() > 0:
            raise PackError(f"sensor: no light reaches the grid over the face (every cell read 0 "
                            f"{self.reading.unit})")
        value, stderr = objective_of(values, err, self.objective)
        return value, stderr, traced

    def packed(self, model: Microstructure, pack_options: dict[str, Any] | None, seed: int,
               out: DesignResult) -> Microstructure:
        """`model` with its density map packed (`pack_options`, kept in ``out.packs``), or as it is (None)."""
        if pack_options is None:
            return model
        result = pack(self.scene, self.instance, model, self.sensor, self.simulation, assign=self.assign, seed=seed,
                      reading=self.reading, cancel=self.cancel, **pack_options)
        out.packs.append(result)
        return result.element

    def confirm(self, base: Microstructure, best: Microstructure, seed: int) -> dict[str, Any] | None:
        """The baseline and the result read with a fresh seed: their objectives, the improvement and its error bar
        (the two errors combined as if independent: an upper bound under shared random numbers); None where a
        cancel cut it short."""
        fresh = int(seed) * CONFIRM_SEED + 1
        start, chosen = self.measure(base, fresh), self.measure(best, fresh)
        if start is None or chosen is None:
            return None
        (b, eb, nb), (r, er, nr) = start, chosen
        gain, gain_err = (r - b if self.goal == "max" else b - r), math.hypot(eb, er)
        return {"seed": fresh, "baseline": b, "baseline_stderr": eb, "objective": r, "stderr": er,
                "improvement": gain, "improvement_stderr": gain_err, "improved": bool(gain > 2.0 * gain_err),
                "photons": nb + nr}


def design(scene: Any, instance: int, start: Microstructure, sensor: dict, simulation: Callable[[Any], Any], *,
           assign: dict[str, Any], parameters: list[Parameter], objective: str = "min_max", goal: str = "max",
           photons: int = 100_000, seed: int = 1, reading: Reading = Reading(),
           pack_options: dict[str, Any] | None = None,
           max_seconds: float = 1800.0, progress: Callable[[dict[str, Any]], None] | None = None,
           cancel: Callable[[], bool] | None = None) -> DesignResult:
    """Tune `parameters` of `start` on `instance` of `scene` (a `tracer.Scene` the caller owns: the loop changes its
    element, and leaves the chosen one on the part) against `objective` read on the grid sensor `sensor`, raised (`goal`
    "max") or lowered ("min") (see the module docstring); `simulation`, `assign` and `reading` as
    `tracer.elements.pack.pack` takes them; `pack_options` (pack's keywords: target, figure, max_iterations, ...) packs
    the density map before and after the sweep, None keeps it. `progress(state)` gets ``{"stage", "candidate",
    "candidates", "objective", "stderr", "photons", "seconds"}`` after each reading (stage "baseline", "sweep" or
    "confirmed"; photons: read so far, the packs' not counted).

    Raises
    ------
    PackError
        See `check`; a pack that cannot run; no light on the grid.
    """
    check(start, parameters, objective, goal)
    if isinstance(photons, bool) or not isinstance(photons, int) or photons < 1000:
        raise PackError(f"photons must be an integer >= 1000, got {photons!r}")
    reading.check()
    t_start = time.perf_counter()
    bench = _Bench(scene, instance, sensor, simulation, assign, int(photons), reading, objective, cancel, goal)
    out = DesignResult(start, {p.name: p.read_from(start.body) for p in parameters}, objective, "done", goal,
                       reading=reading)
    combos = list(itertools.product(*(p.values for p in parameters)))
    traced = [0]

    def say(stage: str, k: int, value: float, err: float, photons: int) -> None:
        traced[0] += photons
        if progress is not None:
            progress({"stage": stage, "candidate": k, "candidates": len(combos), "objective": value, "stderr": err,
                      "photons": traced[0], "seconds": time.perf_counter() - t_start})

    def stopping() -> str | None:
        if cancel is not None and cancel():
            return "cancelled"
        return "seconds" if time.perf_counter() - t_start >= max_seconds else None

    base = bench.packed(start, pack_options, int(seed), out)
    sweep_seed = int(seed) * SWEEP_SEED
    first = bench.measure(base, sweep_seed)
    if first is None:   # cancelled before anything was read whole: the start stays
        out.element, out.stopped, out.seconds = base, "cancelled", time.perf_counter() - t_start
        return out
    v0, e0, n0 = first
    out.baseline = {"values": dict(out.values), "objective": v0, "stderr": e0, "photons": n0}
    say("baseline", -1, v0, e0, n0)
    best_model = _sweep(bench, base, parameters, combos, sweep_seed, out, say, stopping)
    if out.stopped == "done" and best_model is not base:
        best_model = bench.packed(best_model, pack_options, int(seed) + 1, out)
    out.element = best_model
    if out.stopped == "done":
        out.confirmation = bench.confirm(base, best_model, int(seed))
        if out.confirmation is None:
            out.stopped = "cancelled"
        else:
            say("confirmed", -1, out.confirmation["objective"], out.confirmation["stderr"],
                out.confirmation["photons"])
    scene.set_element(instance, best_model, **assign)
    scene.commit()
    out.seconds = time.perf_counter() - t_start
    return out


def _sweep(bench: _Bench, base: Microstructure, parameters: list[Parameter], combos: list[tuple[float, ...]],
           seed: int, out: DesignResult, say: Callable[..., None], stopping: Callable[[], str | None]
           ) -> Microstructure:
    """Read every combination with `base`'s map and the one `seed` (each a `Candidate` in ``out.candidates``; the
    best read sets ``out.values``); answers the best model, `base` where none read better than the baseline.
    ``out.stopped`` says where a cancel or the budget stopped it."""
    best, best_model = out.baseline["objective"], base
    for k, combo in enumerate(combos):
        why = stopping()
        if why is not None:
            out.stopped = why
            break
        c = Candidate(dict(zip((p.name for p in parameters), combo, strict=True)))
        out.candidates.append(c)
        body = base.body
        for p, x in zip(parameters, combo, strict=True):
            body = p.set_in(body, x)
        t0 = time.perf_counter()
        try:
            model = prepare(body)
            got = bench.measure(model, seed)
        except PackError:   # no light on the grid: the design cannot go on
            raise
        except ElementError as exc:   # the body cannot be (a dome taller than its radius), or the face cannot carry it
            c.refused = str(exc)
            continue
        if got is None:   # a partial reading is not taken
            out.candidates.pop()
            out.stopped = "cancelled"
            break
        c.objective, c.stderr, c.photons = got
        c.seconds = time.perf_counter() - t0
        say("sweep", k, c.objective, c.stderr, c.photons)
        if bench.better(c.objective, best):
            best, best_model, out.values = c.objective, model, dict(c.values)
    return best_model
