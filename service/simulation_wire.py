"""The simulation routes' bodies and answers: a query's budget, illuminance at points, a sensor's simulation, jobs.

Every model forbids unknown fields; numbers are finite. `service.routes.simulation` serves them.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

from fastapi import Query
from pydantic import BaseModel, ConfigDict, Field, Strict, field_validator, model_validator

#: A normal may deviate this much from unit length (clients round); it is renormalised before use.
UNIT_TOLERANCE = 1e-3

FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
Vec3 = tuple[FiniteFloat, FiniteFloat, FiniteFloat]
Mode = Annotated[Literal["sync", "async"], Query(description="`async`: answer 202 at once with a job URL.")]
EFFECT_NAME = r"^[a-z_]{1,32}$"


RelativeError = Annotated[float, Strict(), Field(gt=0.0, lt=1.0)]


class QueryBudget(BaseModel):
    """Stopping rules and reproducibility options shared by the query bodies."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    target_relative_error: Annotated[float, Field(gt=0.0, le=1.0)] | None = Field(
        default=None, description="Stop once every value's standard error is below this fraction of it.")
    target_scope: Literal["worst", "lit", "mean"] = Field(
        default="worst", description="Which values `target_relative_error` holds: `worst`, every value; `lit`, every "
                                     "value at least 1 % of the brightest (cells in shadow, which a few stray photons "
                                     "reach, cannot hold a map to its target); `mean`, the mean of the values. The "
                                     "answer's `cost` says what tighter errors would take either way.")
    max_seconds: Annotated[float, Field(gt=0.0)] | None = Field(
        default=None, description="Time budget, s (at most the service's max_seconds).")
    max_photons: Annotated[int, Field(gt=0)] | None = Field(
        default=None, description="Photon budget (at most the service's max_photons).")
    seed: Annotated[int, Field(ge=0, le=2**63 - 1)] = Field(
        default=0, description="Same seed and revision: bit-identical answer.")
    estimator: Literal["auto", "forward", "backward"] = Field(
        default="auto", description="forward photon tracing, backward tracing with next-event estimation, or "
                                    "the scene's choice.")
    force_effects: Annotated[list[Annotated[str, Field(pattern=EFFECT_NAME)]], Field(max_length=16)] = Field(
        default_factory=list, description="Effects to switch on although the scene does not call for them.")
    force_effects_off: Annotated[list[Annotated[str, Field(pattern=EFFECT_NAME)]], Field(max_length=4)] = Field(
        default_factory=list, description="Effects the scene takes by its physics estimate (`polarization`, where a "
                                          "path can meet two polarizing interactions) to leave out of this query: "
                                          "faster, and off by at most what the answer's `effect_reasons` says. One "
                                          "that something in the scene requires (a polarizer, a retarder, a "
                                          "polarized light, observed Stokes) is a 422.")
    observe: Annotated[list[Literal["spectrum", "stokes"]], Field(max_length=2)] = Field(
        default_factory=list, description="`spectrum`: add the spectral irradiance (W/m²/nm in 5 nm bands) and the "
                                          "CIE 1931 chromaticity of each value; photons then carry a wavelength "
                                          "(effect `spectral`). `stokes`: add the Stokes vector (lx) and the degree "
                                          "of polarization in each receiver's frame (effect `polarization`). Either "
                                          "way the forward estimator answers.")
    cost_targets: Annotated[list[RelativeError], Field(min_length=1, max_length=10)] | None = Field(
        default=None, description="The relative errors the answer's `cost` predicts the price of (fractions; "
                                  "default 0.05, 0.02, 0.01, 0.005, 0.002).")
    reference: Vec3 | None = Field(
        default=None, description="With observe stokes: the x axis of each receiver's polarization frame (world), "
                                  "taken onto its plane; default world x, or world y where x is within 25° of "
                                  "the receiver's normal.")
    physics_left_out: Annotated[list[Annotated[str, Field(pattern=EFFECT_NAME)]], Field(max_length=16)] = Field(
        default_factory=list, description="Effects (the names `force_effects` takes) whose share of the answer to "
                                          "measure: for each, the query runs again with the effect forced on, under "
                                          "the same stop rules and budget and an independent seed, and the answer's "
                                          "`physics_left_out` gives that lux minus the answer's (lx per point, with "
                                          "its standard error, lx). Each effect that changes the photons' state "
                                          "(polarization, spectral and the effects needing a wavelength) adds up to "
                                          "one more run's time; one already on, or acting wherever the scene's "
                                          "materials call for it, changes nothing: 0 ± 0 lx, no run. "
                                          "`element_geometry` measures the elements used through their tabulated "
                                          "BSDF (`model: bsdf`): the query runs again with each traced by its exact "
                                          "micro-geometry (0 ± 0 lx, no run, where none is tabulated).")

    tessellation_estimate: Annotated[bool, Strict()] = Field(
        default=False, description="Where the scene has curved mirror or glass meshes (the answer then carries "
                                   "`error_budget.tessellation`, a bound): also estimate the tessellation's error "
                                   "from the surface itself, `error_budget.tessellation_estimate` (lx per value, "
                                   "with its standard error): the query reruns on those meshes split 1→4 two or "
                                   "three times, so it takes 3 to 4 times as long; the answer's "
                                   "`error_budget.tessellation_estimate_seconds` says what it cost. Ignored where "
                                   "the scene has none.")

    @field_validator("observe", "physics_left_out", "force_effects_off")
    @classmethod
    def _once_each(cls, v: list[str], info: Any) -> list[str]:
        if len(set(v)) != len(v):
            raise ValueError(f"{info.field_name} lists each name once, got {v}")
        return v


class CostLine(BaseModel):
    relative_error: float = Field(description="The run's relative error (stderr / lux) at this point.")
    photons: list[int] = Field(description="Photons (forward) or paths (backward) to reach each target.")
    seconds: list[float] = Field(description="Seconds of tracing to reach each target at this run's speed, s.")


class Cost(BaseModel):
    """What tighter errors would cost on this scene and this machine, from the run's own variance and speed (error
    ∝ 1/√photons): for the worst lit point and the median one (`tracer.transport.estimate.cost_of`)."""

    targets: list[float] = Field(description="Relative errors (fractions), in the order of each line's lists.")
    photons_per_second: float = Field(description="This run's tracing speed, photons/s (compilation excluded).")
    worst: CostLine | None = Field(description="At the lit point with the largest relative error; null if none is lit.")
    median: CostLine | None = Field(description="At the median lit point.")
    dark_points: int = Field(description="Points no light reached: no target means anything there.")


class Backend(BaseModel):
    """Where an answer's photon batches ran (`tracer.backends`); the answer is the same wherever they ran."""

    name: Literal["in-process", "dask", "cuda"] = Field(description="`in-process`: threads of the service's own "
                                                                    "process; `dask`: tasks on a Dask cluster; "
                                                                    "`cuda`: the CUDA card, one thread per batch.")
    threads: int | None = Field(None, description="Threads the batches were spread over (all workers' threads for "
                                                  "dask; absent for cuda).")
    address: str | None = Field(None, description="The Dask scheduler's address.")
    workers: int | None = Field(None, description="Dask workers connected when the answer was made.")
    device: str | None = Field(None, description="cuda: the card, `cuda:0 <name>`.")
    fallback: str | None = Field(None, description="Where CUDA was chosen but this query ran on the CPU: why "
                                                   "(`ran on the CPU because` the scene does not fit on the card…).")


class ErrorBudget(BaseModel):
    """Errors beside the Monte Carlo one (`tracer.transport.tessellation_error`), lx per point (per cell for a grid)."""

    tessellation: list[Any] = Field(description="How far each value may move when the curved mirror and glass "
                                                "surfaces are tessellated finely enough (a bound), lx.")
    tessellation_estimate: list[Any] | None = Field(
        None, description="Where the query asked (`tessellation_estimate: true`): an estimate (not a bound) of how "
                          "far each value is from the one a finely tessellated surface gives, lx: the same query "
                          "rerun on the curved meshes split 1→4 two or three times, extrapolated with the observed "
                          "convergence and a safety factor 1.25 (`tracer.transport.tessellation_error."
                          "ESTIMATE_METHOD`).")
    tessellation_estimate_stderr: list[Any] | None = Field(
        None, description="The Monte Carlo standard error of `tessellation_estimate`, lx.")
    tessellation_estimate_seconds: float | None = Field(
        None, description="What the estimate cost: the seconds its reruns and refinements added to the query, s.")
    tessellation_estimate_levels: int | None = Field(
        None, description="How many times the curved meshes were split (each split: one more run of the query).")


class PhysicsLeftOut(BaseModel):
    """What one effect that is off would change (`tracer.simulate.Simulation.left_out`): the lux of a run with it
    forced on minus the answer's lux."""

    difference: list[Any] = Field(description="Lux with the effect on minus the answer's lux, per point (nv rows of "
                                              "nu cells for a grid), lx.")
    stderr: list[Any] = Field(description="Standard error of each difference, √(σ_run² + σ_pilot²), lx.")
    photons: int = Field(description="Photons (or paths) the run with the effect on traced; 0 where none ran.")
    seconds: float = Field(description="Seconds that run took, s.")
    estimator: str | None = Field(None, description="The estimator of that run.")
    ran: bool = Field(description="False where the effect changes nothing that runs (already on, or acting wherever "
                                  "the scene calls for it): the difference is then exactly 0.")


class IlluminanceQuery(QueryBudget):
    """Body of ``POST /scenes/{id}/illuminance``: receivers at points, facing their normals (metres)."""

    points: Annotated[list[Vec3], Field(min_length=1)] = Field(
        description="Receiver centres [x, y, z], world metres.")
    normals: Annotated[list[Vec3], Field(min_length=1)] = Field(
        description="The side each receiver faces: a unit vector per point (dimensionless, length within 1e-3 of 1).")
    radius: Annotated[float, Field(gt=0.0)] | None = Field(
        default=None, description="Radius of each disk receiver, m: each value is the mean illuminance over that "
                                  "disk. Default 0.05 m (`tracer.simulate.DEFAULT_RADIUS`; the answer's `radius` "
                                  "says which was used): ask a smaller one near a small lamp, where the light "
                                  "changes within 5 cm.")

    model_config = ConfigDict(json_schema_extra={"examples": [
        {"points": [[0.0, 0.0, 0.75], [1.0, 1.0, 0.75]], "normals": [[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]],
         "target_relative_error": 0.02, "max_seconds": 30.0, "seed": 1},
        {"points": [[0.5, 0.5, 0.75]], "normals": [[0.0, 0.0, 1.0]], "radius": 0.01, "max_photons": 2_000_000,
         "observe": ["spectrum"], "cost_targets": [0.01, 0.005]}]})

    @model_validator(mode="after")
    def _check(self) -> IlluminanceQuery:
        if len(self.points) != len(self.normals):
            raise ValueError(f"points and normals must have the same length, got {len(self.points)} points and "
                             f"{len(self.normals)} normals")
        for k, n in enumerate(self.normals):
            length = math.hypot(*n)
            if length == 0.0:
                raise ValueError(f"normals[{k}] is the zero vector; each normal must be a unit vector")
            if abs(length - 1.0) > UNIT_TOLERANCE:
                raise ValueError(f"normals[{k}] has length {length:.6g}; each normal must be a unit vector "
                                 f"(length within {UNIT_TOLERANCE:g} of 1)")
        return self


class SensorSimulate(QueryBudget):
    """Body of ``POST /scenes/{id}/sensors/{sid}/simulate`` (all optional)."""

    model_config = ConfigDict(json_schema_extra={"examples": [
        {"target_relative_error": 0.05, "max_seconds": 60.0, "seed": 7},
        {"max_photons": 5_000_000, "estimator": "forward", "cost_targets": [0.02, 0.01]}]})


class RunAnswer(BaseModel):
    """What every answer of a simulation says of its run: photons, time, stop rule, effects, where it ran, what
    tighter errors would cost (`IlluminancePublic`, and every sensor kind's answer: `service.sensor_base`)."""

    model_config = ConfigDict(extra="forbid")

    photons: int = Field(description="Photons (forward) or paths (backward) traced.")
    seconds: float = Field(description="Wall time of the run, s.")
    effects: list[str] = Field(description="The effect set of the scene (and of any forced effects).")
    effect_reasons: dict[str, str] | None = Field(
        None, description="For every effect, why it was on or off in this run (`on: ...` / `off: ...`): what in the "
                          "scene calls for it, or, for polarization, the bound on what leaving it out could move.")
    revision: int = Field(description="Scene revision the answer describes.")
    estimator: str = Field(description="The estimator that ran: `forward` or `backward`.")
    stop_reason: str = Field(description="Which rule stopped the run (target reached, photons, seconds, cancel).")
    compile_seconds: float = Field(0.0, description="Seconds of `seconds` this answer spent compiling (or loading "
                                              "from numba's cache) a kernel first used in this process, s.")
    cost: Cost | None = Field(None, description="What tighter errors would cost (seconds and photons per target).")
    backend: Backend | None = Field(None, description="Where the photon batches ran.")
    device: str | None = Field(None, description="The processor the photon batches ran on: `cuda:0 <card>`, "
                                                 "`cpu:<threads> threads` (… `on <n> dask workers`); where CUDA was "
                                                 "chosen but the scene did not fit, the CPU, and `backend.fallback` "
                                                 "says why.")


class IlluminancePublic(RunAnswer):
    """Answer of an illuminance query (lux ± stderr, one value per point)."""

    model_config = ConfigDict(extra="forbid")

    lux: list[float] = Field(description="Illuminance on each receiver's front side, lx.")
    stderr: list[float] = Field(description="Standard error of each value, lx.")
    elements: list[dict[str, Any]] | None = Field(None, description=(
        "The optical elements with an inside the scene carries, as a sensor's answer names them (with a tabulated "
        "BSDF's `model_error`); absent where it carries none."))
    nm: list[float] | None = Field(None, description="With observe spectrum: centres of the 5 nm bands, nm.")
    spectral_irradiance: list[Any] | None = Field(
        None, description="With observe spectrum: W/m²/nm in each band, one row per point (per cell for a grid).")
    spectral_stderr: list[Any] | None = Field(None, description="Standard error of each band, W/m²/nm.")
    cie_xy: list[Any] | None = Field(
        None, description="With observe spectrum: CIE 1931 (x, y) of the light arriving; null where none arrived.")
    radius: float | None = Field(None, description="Radius of the disk receivers the values are means over, m "
                                                   "(the query's, else the default 0.05 m).")
    warnings: list[str] | None = Field(None, description="Points or lights far outside the model (more than 100 "
                                                         "diagonals of its box): positions are world metres, "
                                                         "whatever the document's length unit; photons that met a "
                                                         "grating where its table of orders ran out.")
    error_budget: ErrorBudget | None = Field(None, description="Where the scene has curved mirror or glass meshes: "
                                                               "the tessellation's share of the error, lx.")
    physics_left_out: dict[str, PhysicsLeftOut] | None = Field(
        None, description="Where the query asked: per effect, what turning it on would change, lx.")
    stokes: list[Any] | None = Field(
        None, description="With observe stokes: [S0, S1, S2, S3] per point, lx (S0 = lux), in the receiver's frame.")
    stokes_stderr: list[Any] | None = Field(None, description="Standard error of each Stokes component, lx.")
    dop: list[Any] | None = Field(
        None, description="With observe stokes: degree of polarization √(S1²+S2²+S3²)/S0; null where none arrived.")


class JobAccepted(BaseModel):
    """Answer 202 to an async request: where to follow the job."""

    model_config = ConfigDict(extra="forbid")

    id: str = Field(description="The job's id.")
    kind: str = Field(description="What the job computes (as `GET /jobs/{id}`'s `kind`).")
    status: str = Field(description="`queued` at first.")
    scene_id: str = Field(description="The scene's id.")
    revision: int = Field(description="Scene revision the job computes.")
    url: str = Field(description="Where to follow it: `GET` it (also the Location header).")


class JobProgress(BaseModel):
    """How far a job got: updated between photon batches."""

    model_config = ConfigDict(extra="forbid")

    photons: int = Field(description="Photons (or paths) traced so far.")
    worst_relative_error: float | None = Field(description="Largest stderr/value over the points so far.")
    seconds: float = Field(description="Time spent so far, s.")
    seconds_left: float | None = Field(
        description="Estimated time to the first stopping rule (target error by the 1/√N law, photons, seconds), "
                    "s, from the tracing rate since the first round: compiling does not make it drift.")
    compile_seconds: float | None = Field(None, description="Seconds the job spent compiling (or loading) its "
                                                            "kernel before the first round, s; null until known.")
    iteration: int | None = Field(None, description="Pack jobs: the iteration being measured (0: the start).")
    measured: int | None = Field(None, description="Pack jobs: the iteration whose figure `uniformity` is (the one "
                                                   "before `iteration` while that one measures); null before any.")
    uniformity: float | None = Field(None, description="Pack jobs: the figure (min/max or min/mean) of iteration "
                                                       "`measured`.")
    uniformity_stderr: float | None = Field(None, description="Pack jobs: its standard error.")
    fraction: float | None = Field(None, description="Prepare jobs: the fraction of the grating's table solved.")
    points: int | None = Field(None, description="Prepare jobs: table points solved (each side of the face counts).")
    points_total: int | None = Field(None, description="Prepare jobs: table points to solve.")
    stage: Literal["baseline", "sweep", "confirmed"] | None = Field(
        None, description="Design jobs: the reading last taken: the baseline, a candidate of the sweep, or the "
                          "confirmation on a fresh seed.")
    candidate: int | None = Field(None, description="Design jobs: the candidate last read (-1: the baseline or "
                                                    "the confirmation).")
    candidates: int | None = Field(None, description="Design jobs: the combinations to sweep.")
    objective: float | None = Field(None, description="Design jobs: the objective of that reading.")
    objective_stderr: float | None = Field(None, description="Design jobs: its standard error.")


class JobPublic(BaseModel):
    """A job as ``GET /jobs/{id}`` shows it."""

    model_config = ConfigDict(extra="forbid")

    id: str = Field(description="The job's id.")
    kind: Literal["illuminance", "sensor", "uniformity", "conoscope", "pack", "design", "prepare"] = Field(
        description="A point query, a sensor simulation, luminance meters (`uniformity`, `conoscope`), a pack of a "
                    "density element, a design loop over an element's parameters, or the preparation of a grating "
                    "(`POST /elements?mode=async`: no scene, `scene_id` empty; its result the element's summary).")
    status: Literal["queued", "running", "succeeded", "failed", "cancelled"] = Field(description="Where it is.")
    scene_id: str = Field(description="The scene's id.")
    revision: int = Field(description="Scene revision the job computes.")
    current: bool = Field(description="False once the scene changed after the job started (push or assignment).")
    cancel_requested: bool = Field(description="True once `DELETE /jobs/{id}` asked it to stop.")
    created_at: float = Field(description="When it was queued, Unix time, s.")
    started_at: float | None = Field(description="When it started, Unix time, s; null while queued.")
    finished_at: float | None = Field(description="When it ended, Unix time, s; null until then.")
    progress: JobProgress = Field(description="How far it got.")
    result: dict[str, Any] | None = Field(
        description="The answer of the sync call (IlluminancePublic, or the sensor kind's answer; a prepare job's: "
                    "the element's summary); a cancelled job keeps its partial answer.")
    error: str | None = Field(description="Why it failed; null otherwise.")
    url: str = Field(description="This job's URL.")
    points: int | None = Field(None, description="Illuminance jobs: how many points; prepare jobs: table points "
                                                 "(each side of the face counts).")
    sensor: str | None = Field(None, description="Sensor, pack and design jobs: the sensor's id.")
    element: str | None = Field(None, description="Pack and design jobs: the element they start from.")
    estimate_seconds: float | None = Field(None, description="Prepare jobs: the cost estimated before solving, s.")
