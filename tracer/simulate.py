"""The query: `Simulation` (docs/CONTRACTS.md, "light transport → service").

A `Simulation` holds a committed `tracer.Scene`, the material of every instance, and the lights, all
validated once. `run(sensor, ...)` measures any sensor kind of `tracer.sensors` (a body ``{"type": ..., ...}``:
points, disk, grid, surface, far field; each kind's module says what it answers, in which units and shape). The
named queries are thin calls of it: `illuminance(points, normals, radius)` (lx on small disks), `grid(origin, u, v,
nu, nv)` (an (nv, nu) map of cell averages), `surface(instances)` (lx per triangle of the model),
`far_field(nc, ngamma, direction, c0)` (cd on a type-C grid).

Both estimators estimate exactly the receivers' patch averages, so they agree within their error bars:
- ``"forward"`` (`tracer.transport.forward`): photons from the sources, recorded by the query's own receivers:
  sensor instances (`Scene.add_disk_sensor` / `add_rect_sensor`) in a small scene of their own beside
  the scene, which a query only reads (so queries on one scene may run at once, and nobody copies it);
- ``"backward"`` (`tracer.transport.backward`): paths from uniform points of each patch with next-event
  estimation; only where every surface is purely diffuse (its kind says so) and every light can be
  reached by a shadow ray (its kind says so). ``"auto"`` takes it for points and disks where it applies,
  and forward otherwise (grids; surface and far-field sensors are forward only); the result says which ran.

A receiver on a surface is placed on the surface the rays meet, just in front (`tracer.sensors.placement`).

Estimation (`tracer.transport.rounds`): independent batches seeded from (seed, batch index) through the counter-based
`tracer.rng`; batch sizes depend only on the request and the backend's `tracer.backends.BatchShape`, batches are
started in rounds of `ROUND_BATCHES`, growing to a quarter of the batches run so far (at most `MAX_ROUND_BATCHES`,
and `MAX_ROUND_BYTES` of tallies: a long query gives a cluster's workers tasks of 0.1 s or more while a stop
overshoots its rule by at most a quarter; a GPU's shape has thousands of small batches a round), and the
stop test runs between rounds, so for the same seed and stop rule (target error or photon budget) the answer is
bit-identical whatever the number of threads, processes or machines the batches of one shape ran on. Standard errors
are batch means (`tracer.transport.estimate`). A query stops when every point's relative error is at most
`target_relative_error` (``"target_relative_error"``), at `max_photons` (``"max_photons"``),
`max_seconds` (``"max_seconds"``) or when `cancel()` is truthy (``"cancelled"``). Without any
budget it runs `DEFAULT_MAX_SECONDS`. Every answer has at least two batches (an error bar needs two),
so a photon budget below two batches' worth (`max_photons: 1`) runs two batches of the smallest size.
A patch that received nothing in every batch so far counts as converged (0 ± 0): a point in full
shadow does not hold a query to its time budget, but a forward query for a very small receiver far
from the light can stop at 0 early; give it a photon budget.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from collections import Counter
from typing import Any

import numpy as np

from tracer.backends import IN_PROCESS, Shipment, is_backend
from tracer.effects import (
    BASELINE,
    OPTIONAL,
    EffectError,
    check_off,
    explain_effects,
    met_twice,
    photon_state,
    query_reasons,
    with_forced,
)
from tracer.elements.diffraction import diattenuation
from tracer.errors import SimulationError
from tracer.optics.lights import connectable, pack_lights
from tracer.optics.lights.dispatch import polarized_lights, spectral_lights
from tracer.optics.surfaces.dispatch import backward_ok, material_spec, pack_materials
from tracer.sensors import dispatch as sensors
from tracer.sensors.base import IlluminanceResult, Probe, vec3
from tracer.sensors.far_field import FarFieldResult, far_field_bins
from tracer.sensors.grid import GridResult
from tracer.sensors.placement import place_receivers, probe_distance, sensor_offset
from tracer.sensors.points import DEFAULT_RADIUS
from tracer.sensors.surface import SurfaceResult
from tracer.transport.estimate import cost_of
from tracer.transport.query import DEFAULT_MAX_SECONDS, ESTIMATORS, LEFT_OUT_MODELS, OBSERVABLES, TARGET_SCOPES, Query
from tracer.transport.query import query as make_query
from tracer.transport.rounds import (
    BACKWARD_BATCH,
    FORWARD_BATCH,
    LIT_FRACTION,
    MAX_ROUND_BATCHES,
    MAX_ROUND_BYTES,
    MAX_SPECTRAL_TALLIES,
    MIN_BATCHES,
    ROUND_BATCHES,
    QueryBackend,
    backward,
    compile_seconds,
    forward,
    radiance,
)
from tracer.transport.tessellation_error import (
    MAX_LEVELS,
    MAX_TRIANGLES,
    MIN_LEVELS,
    converged,
    extrapolate,
    grid_cells,
    lux_budget,
    refine,
    scene_surfaces,
)

__all__ = ["BACKWARD_BATCH", "DEFAULT_MAX_SECONDS", "DEFAULT_RADIUS", "ESTIMATORS", "FORWARD_BATCH", "LIT_FRACTION",
           "MAX_ROUND_BATCHES", "MAX_ROUND_BYTES", "MAX_SPECTRAL_TALLIES", "MIN_BATCHES", "OBSERVABLES",
           "ROUND_BATCHES", "TARGET_SCOPES", "FarFieldResult", "GridResult", "IlluminanceResult", "Simulation",
           "SimulationError", "SurfaceResult", "compile_seconds", "far_field_bins", "place_receivers",
           "probe_distance", "sensor_offset"]

log = logging.getLogger(__name__)


class Simulation:
    """Light transport over one committed scene (docs/CONTRACTS.md).

    Parameters
    ----------
    scene : tracer.Scene
        Committed. Queries add their receivers as sensor instances for their duration (under a
        lock: queries of one `Simulation` run one at a time on the scene).
    materials : {instance id: material body}
        docs/DESIGN.md material bodies, or their typed specs (`tracer.optics.surfaces`).
    lights : list of light bodies
        World metres (`tracer.optics.lights`); area lights carry ``"instances"``.
    default_material : material body, optional
        For instances not in `materials`; without it every non-sensor instance needs a material.
    backend : `tracer.backends.InProcess`, `DaskBackend` or `tracer.gpu.backend.CudaBackend`, optional
        Where the batches run; default this process's threads. The answer is the same wherever they run (within
        error bars on a GPU). A query whose scene does not fit on the card runs on this process's threads, and its
        result's `backend` says why (``"fallback"``).

    Raises
    ------
    SimulationError, MaterialError, LightError (all ValueError)
        Saying which body or field is wrong.
    """

    def __init__(self, scene, materials: dict[int, dict], lights: list[dict], default_material: dict | None = None,
                 backend: Any = None):
        if scene is None or not hasattr(scene, "arrays"):
            raise SimulationError("scene must be a tracer.Scene")
        if getattr(scene, "dirty", False) is True:
            raise SimulationError("the scene has changes that are not committed: call scene.commit() first")
        if not isinstance(materials, dict):
            raise SimulationError(f"materials must be a dict {{instance id: body}}, got {type(materials).__name__}")
        if backend is not None and not is_backend(backend):
            raise SimulationError(f"backend must be a tracer.backends backend, got {type(backend).__name__}")
        self.backend = IN_PROCESS if backend is None else backend
        self._inputs = (materials, lights, default_material)   # what `refined` rebuilds from (validated below)
        self._refined: Simulation | None = None
        self._exact: Simulation | None = None   # `exact_elements`
        self._shipments: dict[str, Shipment] = {}   # the snapshot each kernel reads, per photon state
        self.scene = scene
        self.arrays = scene.arrays()   # the committed scene, read-only from here on
        ids = [int(i) for i in scene.instances()]
        self.sensor_ids = {i for i in ids if _is_sensor(scene, i)}   # sensors: no surface
        mats = {}
        for key, body in materials.items():
            if isinstance(key, bool) or not isinstance(key, int | np.integer):
                raise SimulationError(f"materials: keys must be instance ids (int), got {key!r}")
            if int(key) not in self.sensor_ids:   # a sensor has no surface: nothing to assign
                mats[int(key)] = material_spec(body, f"material of instance {int(key)}")
        default_spec = material_spec(default_material, "default_material") if default_material is not None else None
        self._mats = pack_materials(mats, default_spec, ids, self.sensor_ids)
        self._lights = pack_lights(list(lights), scene, frozenset(self.sensor_ids))
        self.light_bodies: list[dict] = [dict(b) for b in lights]   # validated: what the luminance kernel reads
        self._lights_spectral = spectral_lights(self._lights)   # the same lights for photons with a wavelength
        geometry_ids = [i for i in ids if i not in self.sensor_ids]
        # the distinct specs in use (a scene of 100k instances has a handful of materials)
        self._specs = list(dict.fromkeys(m for m in (mats.get(i, default_spec) for i in geometry_ids) if m is not None))
        counts = Counter(m for m in (mats.get(i, default_spec) for i in geometry_ids) if m is not None)
        # the one rule, as the service's summary: the effect set, and why each effect is on or off
        twice = met_twice(scene, {i: mats.get(i, default_spec) for i in geometry_ids}, counts, lights)
        gratings = [diattenuation(t) for t in scene.gratings()] if hasattr(scene, "gratings") else []
        self.effects, self.effect_reasons = explain_effects(self._specs, lights, counts, twice, gratings)
        self._curved = scene_surfaces(scene, {i: mats.get(i, default_spec) for i in geometry_ids}, geometry_ids)

    # ------------------------------------------------------------------------------------------ helpers

    def backward_applies(self, effects: list[str] | None = None) -> tuple[bool, str]:
        """Whether the backward estimator can answer for this scene (and effect set), and if not why."""
        effects = self.effects if effects is None else effects
        ok, why = backward_ok(self._specs)   # first: it names the material kind
        if not ok:
            return False, why
        if set(effects) - {BASELINE}:
            return False, (f"the scene needs {sorted(set(effects) - {BASELINE})}: point-like sources cannot be "
                           f"reached through specular or refractive surfaces by shadow rays")
        return connectable(self._lights)

    def _choose(self, estimator: str, effects: list[str], grid: bool) -> str:
        if estimator not in ESTIMATORS:
            raise SimulationError(f"estimator must be one of {list(ESTIMATORS)}, got {estimator!r}")
        ok, why = self.backward_applies(effects)
        if estimator == "backward" and not ok:
            raise SimulationError(f"the backward estimator cannot answer here: {why}; use 'forward' or 'auto'")
        if estimator == "auto":
            return "backward" if (ok and not grid) else "forward"
        return estimator

    # ------------------------------------------------------------------------------------------ queries

    def run(self, sensor: dict, *, query: Query | None = None, progress=None, cancel=None, **options) -> Any:
        """Measure one sensor: a body ``{"type": kind, ...}`` of a registered kind (`tracer.sensors.dispatch.KINDS`);
        its answer (the kind's result: `IlluminanceResult`, `GridResult`, `SurfaceResult`, `FarFieldResult`).

        The request is one `tracer.transport.query.Query`, given as `query` (as the service builds it) or as the
        options below (checked once, by `tracer.transport.query.query`), not both:

        target_relative_error, max_seconds, max_photons : stop rules (see the module docstring).
        target_scope : which relative error the target holds: "worst" (every value's), "lit" (every value at
            least `LIT_FRACTION` of the brightest) or "mean" (the mean of the values').
        seed : int ≥ 0.  estimator : "auto", "forward" or "backward".
        force_effects : effect names to compile in although the scene does not need them.
        force_effects_off : effects the scene takes by its physics estimate (`tracer.effects.OPTIONAL`:
            polarization) to leave out of this query; one that something in the scene requires is refused.
        observe : ("spectrum",) to add the spectral irradiance and the chromaticity (`IlluminanceResult`);
            photons then carry a wavelength (effect `spectral`), and the forward estimator answers. "stokes" adds
            the Stokes vector and the degree of polarization (effect `polarization`).
        reference : (3,) float, optional
            The x axis of the receivers' polarization frames (world), taken onto each receiver's plane; default
            world x, or world y where x is within 25° of the receiver's normal.
        physics_left_out : effect names (`tracer.effects.EFFECTS`) whose share of the answer to measure, or
            ``"element_geometry"``: how far the elements used through their tabulated BSDF are from their exact
            micro-geometry; the result's `physics_left_out` (`left_out`).
        tessellation_estimate : bool — where the scene has curved mirror or glass meshes, also run the query on
            those meshes refined 1→4, twice or three times (`tessellation_levels`; the same stop rules and seed, so
            up to 3 or 4 times the time) and add to the result's `error_budget` ``tessellation_estimate`` and
            ``tessellation_estimate_stderr`` (lx per value), an estimate of the tessellation's error, not a bound
            (`tracer.transport.tessellation_error.ESTIMATE_METHOD`), with what it cost:
            ``tessellation_estimate_seconds`` and ``tessellation_estimate_levels``.
        progress : callable(photons, worst_relative_error, seconds), called once before the first round (0
            photons: `seconds` is what compiling or loading the kernel took) and between rounds.
        cancel : callable() -> bool, polled between rounds.
        """
        return sensors.run(self, sensor, _query_of(query, options), progress, cancel)

    def illuminance(self, points, normals, radius=None, **query) -> IlluminanceResult:
        """Illuminance (lx) on the front side of a disk receiver at each point ((k, 3) m; normals any non-zero
        length; radius m, default `DEFAULT_RADIUS`): `tracer.sensors.points`. Query options as for `run`."""
        return self.run({"type": "points", "points": points, "normals": normals, "radius": radius}, **query)

    def grid(self, origin, u, v, nu, nv, **query) -> GridResult:
        """Cell-average illuminance (lx) over a grid origin + s u + t v, front side u × v, as (nv, nu) arrays:
        `tracer.sensors.grid`. Query options as for `run`."""
        return self.run({"type": "grid", "origin": origin, "u": u, "v": v, "nu": nu, "nv": nv}, **query)

    def surface(self, instances, **query) -> SurfaceResult:
        """Per-triangle illuminance (lx) on the front side of each instance listed: `tracer.sensors.surface`.
        Query options as for `run`. Forward only."""
        return self.run({"type": "surface", "instances": instances}, **query)

    def far_field(self, nc, ngamma, direction=(0.0, 0.0, -1.0), c0=None, **query) -> FarFieldResult:
        """Luminous intensity (cd) of the whole scene seen from far away, on a type-C grid of `nc` C and `ngamma` γ
        samples, γ from `direction`, C from `c0`: `tracer.sensors.far_field`. Query options as for `run`."""
        return self.run({"type": "far_field", "nc": nc, "ngamma": ngamma, "direction": direction, "c0": c0}, **query)

    def measure(self, probe_of, body: dict, query: Query, progress=None,
                cancel=None) -> tuple[Probe, IlluminanceResult]:
        """A sensor's receivers (`probe_of(self, body)`) and the raw bins measured on them for `query`, with what each
        effect in its `physics_left_out` would change (`left_out`): what `tracer.sensors.dispatch.run` shapes into an
        answer."""
        if query.tessellation_estimate and self._curved and \
                curved_triangles(self) * 4 ** MIN_LEVELS > MAX_TRIANGLES:
            raise SimulationError(f"tessellation_estimate: the curved meshes have {curved_triangles(self):,} "
                                  f"triangles; {MIN_LEVELS} splits would make more than {MAX_TRIANGLES:,}")
        probe = probe_of(self, body)
        res = self._run(probe, query, progress, cancel)
        if query.physics_left_out:
            res.physics_left_out = left_out(self, res, query,
                                            lambda pilot, sim=self: sim._run(probe, pilot, None, cancel))
        if query.tessellation_estimate and res.error_budget and res.stop_reason != "cancelled":
            res.error_budget.update(tessellation_levels(self, res, lambda sim: sim._run(probe, query, None, cancel)))
        return probe, res

    # ------------------------------------------------------------------------------------------ engine

    def _run(self, probe: Probe, query: Query, progress, cancel) -> IlluminanceResult:
        """One run of `query` over `probe`'s receivers: the raw bins (a surface tally's after the receivers', then a
        far field's: cd, then the total flux leaving, lm)."""
        stop = query.budget.stop_rules()
        observe_spectrum, observe_stokes = query.observes
        force_effects, force_effects_off, seed, estimator = (query.forced, query.force_effects_off, query.seed,
                                                             query.estimator)
        refs = _references(query.reference, np.atleast_2d(probe.normals))
        try:
            effects = with_forced(self.effects, force_effects)
        except EffectError as exc:
            raise SimulationError(f"{exc} (in force_effects)") from None
        try:
            off = check_off(force_effects_off, force_effects, self.effect_reasons)
        except EffectError as exc:
            raise SimulationError(str(exc)) from None
        effects = with_forced(effects, (), off)
        if probe.view is not None:   # a luminance meter or a camera: paths from the eye
            # polarization taken by the physics estimate is left out (those paths carry no Stokes vector); forced
            # or required, radiance refuses it
            dropped = tuple(e for e in OPTIONAL if e in effects and e not in (force_effects or ())
                            and not self.effect_reasons.get(e, "").startswith("on: required"))
            out = radiance(self, probe, stop, int(seed), estimator, with_forced(effects, (), dropped), progress,
                           cancel, QueryBackend(self.backend))
            out.effect_reasons = query_reasons(self.effect_reasons, out.effects, force_effects, off)
            for e in dropped:
                out.effect_reasons[e] = ("off: paths from the eye (luminance) carry no Stokes vector; the scene "
                                         f"would take it: {self.effect_reasons[e][4:]}")
            return out
        which = self._choose(estimator, effects, probe.is_grid)
        if (probe.surface is not None or probe.far is not None) and which != "forward":
            raise SimulationError("the surface and far-field tallies are forward only")
        if which == "backward":
            effects = [BASELINE]
        t0 = time.perf_counter()
        backend = QueryBackend(self.backend)
        if which == "forward":
            res = forward(self, probe, stop, int(seed), effects, progress, cancel, t0, observe_spectrum,
                          refs if observe_stokes else None, backend)
        else:
            res = backward(self, probe, stop, int(seed), effects, progress, cancel, t0, backend)
        res.cost = cost_of(res.lux, res.stderr, res.photons, res.seconds - res.compile_seconds)
        if self._curved and probe.surface is None and probe.far is None:
            if probe.is_grid:
                grid: Any = probe.grid
                cell_centres, cell = grid_cells(probe.centers, *grid)
                budget_lux = lux_budget(res.lux, cell_centres, self._curved, cell=cell)
            else:
                budget_lux = lux_budget(res.lux, probe.centers, self._curved, radius=probe.radius)
            res.error_budget = {"tessellation": budget_lux}
        res.backend = backend.describe()
        res.effect_reasons = query_reasons(self.effect_reasons, res.effects, force_effects, off)
        return res

    def snapshot(self, state: str) -> Shipment:
        """The read-only scene a kernel takes (arrays, materials, lights packed for the photon state), one
        `Shipment` per state for the life of this simulation: sent to a cluster's workers once."""
        if state not in self._shipments:
            lights = self._lights_spectral if state.endswith("spectral") else self._lights
            if state.startswith("polarized"):
                lights = polarized_lights(lights)
            self._shipments[state] = Shipment((self.arrays, self._mats, lights))
        return self._shipments[state]


def _query_of(query: Query | None, options: dict) -> Query:
    """The query `Simulation.run` was given, or the one its options make (checked once, `make_query`)."""
    if query is None:
        return make_query(**options)
    if options:
        raise SimulationError(f"give a query or its options ({sorted(options)}), not both")
    if not isinstance(query, Query):
        raise SimulationError(f"query must be a tracer.transport.query.Query, got {type(query).__name__}")
    return query


def _pilot_seed(seed: int, k: int) -> int:
    """The seed of the k-th pilot of a query with `seed`: a stream of its own (`tracer.rng` seeds by (seed, batch))."""
    return (int(seed) + (k + 1) * 0x9E3779B97F4A7C15) % 2 ** 63


def _references(reference, normals: np.ndarray) -> np.ndarray:
    """(k, 3) unit x axes of the receivers' polarization frames: `reference` (default world x, world y where x is
    within 25° of the normal) taken onto each receiver's plane (unit normals (k, 3))."""
    if reference is None:
        x = np.tile([1.0, 0.0, 0.0], (len(normals), 1))
        x[np.abs(normals[:, 0]) > math.cos(math.radians(25.0))] = [0.0, 1.0, 0.0]
    else:
        x = np.tile(vec3(reference, "reference"), (len(normals), 1))
    x = x - (x * normals).sum(axis=1)[:, None] * normals
    ln = np.linalg.norm(x, axis=1)
    if np.any(ln <= 1e-9):
        raise SimulationError(f"reference {reference!r} lies along the normal of receiver "
                              f"{int(np.argmax(ln <= 1e-9))}: give an axis in the receiver's plane")
    return x / ln[:, None]


def _is_sensor(scene, i: int) -> bool:
    fn = getattr(scene, "is_sensor", None)
    if fn is not None:
        return bool(fn(i))
    try:
        scene.instance_geometry(i)
    except Exception:
        return True
    return False


# ------------------------------------------------------------------------------------------ physics left out
def left_out(sim: Simulation, res: IlluminanceResult, query: Query, rerun) -> dict:
    """What each effect in the query's `physics_left_out` would change (docs/DESIGN.md, "Accuracy is a quantity"):
    per effect ``{"difference": lux with it forced on − res.lux, "stderr": √(σ_run² + σ_pilot²), "photons",
    "seconds", "estimator" of the pilot, "ran"}``.

    The pilot (`rerun(pilot query, simulation)`) is the same query with the effect forced on, under the
    query's own stop rules (its target error, photon and time budget: the difference's error is then about √2
    times the run's own, and the answer takes up to 1 + (effects named) times as long) and an independent seed
    (`_pilot_seed`: the two estimates are independent, so their variances add). An effect that leaves the photon
    state the same (`tracer.effects.photon_state`) changes nothing that runs: it is already on, or a branch on data
    that acts wherever the scene's materials call for it (Fresnel wherever there is a dielectric); its difference
    is exactly 0 ± 0 and no pilot runs (``"ran": false``). What a pilot can change today is therefore the light's
    state: polarization (polarized Fresnel instead of the s/p average) and a wavelength per photon (spectral and
    the effects that need it). An effect the query forced off (`force_effects_off`) is measured the same way: the
    pilot turns it back on. ``"element_geometry"`` (`LEFT_OUT_MODELS`) measures the elements used through their
    tabulated BSDF: the pilot runs on the scene with each traced by its exact micro-geometry (`exact_elements`;
    0 ± 0, no pilot, where no element is tabulated). A cancelled run runs no pilot (``{}``).
    """
    if res.stop_reason == "cancelled":
        return {}
    asked, off = query.forced, query.force_effects_off
    base = with_forced(sim.effects, asked, off)
    pilot_estimator = "forward" if query.estimator == "forward" else "auto"
    out = {}
    for k, name in enumerate(query.physics_left_out):
        on: Simulation | None = sim   # what the pilot runs on; None: nothing would change
        if name in LEFT_OUT_MODELS:
            on, force = exact_elements(sim), asked
        else:
            force = (*asked, name)
            if photon_state(with_forced(base, name)) == photon_state(base):
                on = None
        if on is None:
            zero = np.zeros_like(res.lux)
            out[name] = {"difference": zero, "stderr": zero.copy(), "photons": 0, "seconds": 0.0,
                         "estimator": None, "ran": False}
            continue
        pilot = rerun(dataclasses.replace(query, seed=_pilot_seed(query.seed, k), estimator=pilot_estimator,
                                          force_effects=force, observe=(), reference=None, physics_left_out=(),
                                          tessellation_estimate=False,
                                          force_effects_off=tuple(e for e in off if e not in force)), on)
        out[name] = {"difference": pilot.lux - res.lux, "stderr": np.hypot(pilot.stderr, res.stderr),
                     "photons": int(pilot.photons), "seconds": float(pilot.seconds),
                     "estimator": pilot.estimator, "ran": True}
    return out


def exact_elements(sim: Simulation) -> Simulation | None:
    """The same simulation with every element that a tabulated BSDF stands for traced by its exact micro-geometry
    (`tracer.Scene.exact_elements`), built once; None where the scene has no tabulated element."""
    if not sim.scene.tabulated_elements():
        return None
    if sim._exact is None:
        import copy

        materials, lights, default = sim._inputs
        scene = copy.deepcopy(sim.scene)
        scene.exact_elements()
        scene.commit()
        sim._exact = Simulation(scene, materials, lights, default, sim.backend)
    return sim._exact


# ------------------------------------------------------------------------------------------ tessellation
def tessellation_levels(sim: Simulation, res: IlluminanceResult, rerun) -> dict:
    """The tessellation estimate (`tracer.transport.tessellation_error.extrapolate`) of `res`, the query's answer
    on `sim`: `rerun(s)` answers the same query on `s`, here `sim` refined once, twice (`MIN_LEVELS`) and, where
    the values are not yet in the asymptotic range (`converged`), three times (`MAX_LEVELS`, while the refined
    curved meshes stay under `MAX_TRIANGLES`). A cancelled rerun stops the estimate ({}). Returns the
    ``error_budget`` entries: ``tessellation_estimate`` and ``_stderr`` (lx, like ``res.lux``),
    ``tessellation_estimate_seconds`` (s: what the estimate added to the query, refinement included) and
    ``tessellation_estimate_levels`` (the splits run)."""
    t0 = time.perf_counter()
    lux, err = [np.asarray(res.lux, np.float64)], [np.asarray(res.stderr, np.float64)]
    s = sim
    for level in range(1, MAX_LEVELS + 1):
        if level > MIN_LEVELS and (converged(lux, err) or curved_triangles(s) * 4 > MAX_TRIANGLES):
            break
        s = refined(s)
        r = rerun(s)
        if r.stop_reason == "cancelled":
            return {}
        lux.append(np.asarray(r.lux, np.float64))
        err.append(np.asarray(r.stderr, np.float64))
    estimate, se, _ = extrapolate(lux, err)
    shape = np.shape(res.lux)
    return {"tessellation_estimate": estimate.reshape(shape), "tessellation_estimate_stderr": se.reshape(shape),
            "tessellation_estimate_seconds": time.perf_counter() - t0, "tessellation_estimate_levels": len(lux) - 1}


def curved_triangles(sim: Simulation) -> int:
    """Triangles in the meshes of `sim`'s curved mirror and glass instances (each geometry once)."""
    gids = {sim.scene.instance_geometry(s.instance) for s in sim._curved if s.instance >= 0}
    return sum(len(sim.scene.geometry_arrays(g)[1]) for g in gids)


def refined(sim: Simulation) -> Simulation:
    """The same simulation with every curved mirror or glass mesh (`scene_surfaces`) split 1→4 along the
    curve its vertex normals describe (`tracer.transport.tessellation_error.refine`); built once. An instance
    that carries an element keeps its mesh."""
    if sim._refined is None:
        import copy

        materials, lights, default = sim._inputs
        scene = copy.deepcopy(sim.scene)
        materials = dict(materials)
        done: dict[str, str] = {}
        for s in sim._curved:
            i = s.instance
            if i < 0 or scene.elements_on(i):
                continue
            gid = scene.instance_geometry(i)
            if gid not in done:
                v, t, n = scene.geometry_arrays(gid)
                ids = scene.face_ids(gid)   # refine's four children of each triangle come in four blocks
                done[gid] = scene.add_geometry(*refine(v, t, n), face_ids=None if ids is None else np.tile(ids, 4))
            j = scene.add_instance(done[gid], scene.instance_transform(i))
            scene.remove_instance(i)
            if i in materials:
                materials[j] = materials.pop(i)
        scene.commit()
        sim._refined = Simulation(scene, materials, lights, default, sim.backend)
    return sim._refined
