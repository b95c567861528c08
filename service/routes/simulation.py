"""Simulation routes: illuminance at points, grid sensor simulation and maps, async jobs.

- ``POST /scenes/{id}/illuminance`` — lux ± standard error at points (``?mode=async`` → 202 + job);
- ``POST /scenes/{id}/sensors/{sid}/simulate`` — simulate a grid, disk or surface sensor (``?mode=async`` too); a
  surface sensor answers per instance of its node's subtree (``instances``: node, path, lux and stderr per
  triangle, `service.simulation.SimulationHub._run_surface`);
- ``GET /scenes/{id}/sensors/{sid}/map.png`` — the false-colour map of the sensor's latest result;
- ``GET /scenes/{id}/sensors/{sid}/export?format=ies|ldt`` — a far-field sensor's latest result as an IES LM-63-2002
  or EULUMDAT file (`tracer.photometry.export`);
- ``GET /jobs/{jid}``, ``DELETE /jobs/{jid}`` — progress and result of a job; cancel it.

Every answer names the scene revision it was computed at; a push or an assignment makes earlier
results stale (a job says ``current: false``, a sensor map is gone until simulated again).
The handlers are plain functions, so FastAPI runs them in worker threads: a query never blocks
the event loop, and the hub bounds how many run at once.
"""

from __future__ import annotations

import math
import re
from typing import Annotated, Any, Literal

import numpy as np
from fastapi import APIRouter, Query, Request, Response
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import JSONResponse

from service import units
from service.errors import Invalid, NotFound, TooLarge
from service.jobs import JobNotFound, QueueFull
from service.maps import colour_map_png, illuminance_map_png, luminance_map_png
from service.routes.deps import ItemId, JobId, MapScale, MapVmin, SceneId, map_range
from service.sensor_kinds import SensorPublic, kind_of, types_where
from service.simulation import SimulationHub, Unavailable, find_sensor, hub_for, request_query
from service.simulation_wire import (  # noqa: F401 (the route's models, named here too)
    UNIT_TOLERANCE,
    Backend,
    Cost,
    ErrorBudget,
    IlluminancePublic,
    IlluminanceQuery,
    JobAccepted,
    JobProgress,
    JobPublic,
    Mode,
    PhysicsLeftOut,
    SensorSimulate,
)
from tracer.transport.estimate import cost_of

router = APIRouter(tags=["simulation"])

def _hub(request: Request) -> SimulationHub:
    return hub_for(request.app)


def _accepted(request: Request, job: Any) -> JSONResponse:
    url = str(request.url_for("get_job", job_id=job.id).path)
    body = JobAccepted(id=job.id, kind=job.kind, status=job.status.value, scene_id=job.scene_id,
                       revision=job.revision, url=url)
    return JSONResponse(body.model_dump(), status_code=202, headers={"Location": url})


def _submit(hub: SimulationHub, kind: str, scene_id: str, revision: int, work: Any, budget: Any,
            meta: dict[str, Any]) -> Any:
    try:
        return hub.jobs.submit(kind, scene_id, revision, work, budget, meta)
    except QueueFull as exc:
        raise Unavailable(f"the job queue is full: {exc}", retry_after_seconds=10) from exc


@router.post("/scenes/{scene_id}/illuminance", response_model=IlluminancePublic, response_model_exclude_none=True,
             responses={202: {"model": JobAccepted}, 413: {}, 503: {}})
async def illuminance(scene_id: SceneId, query: IlluminanceQuery, request: Request, mode: Mode = "sync") -> Any:
    """Illuminance (lx) with its standard error at each point, for receivers facing `normals`."""
    return await _answer(request, mode, _points_query, scene_id, query, request)


async def _answer(request: Request, mode: str, setup: Any, *args: Any) -> Any:
    """Set a query up in a worker thread (validation, the scene's snapshot), then queue it as a job or run it in
    one of the sync slots. The wait for a slot holds no thread: waiting queries never starve the threads that
    serve pushes, health probes and reads (`SimulationHub.slot`)."""
    hub = _hub(request)
    kind, scene_id, prepared, work, budget, meta = await run_in_threadpool(setup, *args)
    if mode == "async":
        job = _submit(hub, kind, scene_id, prepared.live.revision, work, budget, meta)
        return _accepted(request, job)
    async with hub.slot():
        payload = await run_in_threadpool(work)
    payload.pop("current", None)
    return payload


def _targeted(payload: dict[str, Any], targets: list[float] | None) -> None:
    """The answer's `cost` for the query's own targets (the tracer's holds the default ones)."""
    if targets:
        values = next(payload[k] for k in ("lux", "candela", "luminance") if k in payload)
        payload["cost"] = cost_of(values, payload["stderr"], payload["photons"],
                                  payload["seconds"] - payload["compile_seconds"], targets)


PILOT_SECONDS = 2.0   # s: the pilot run of a plan, unless the query asks for less


@router.post("/scenes/{scene_id}/illuminance/plan", response_model=IlluminancePublic,
             response_model_exclude_none=True, responses={413: {}, 503: {}})
async def plan_illuminance(scene_id: SceneId, query: IlluminanceQuery, request: Request) -> Any:
    """What an illuminance query would cost before it is run: a short pilot (at most 2 s, or the query's own
    smaller budget; no target) answers its lux and, in `cost`, the seconds and photons each target would take."""
    pilot = query.model_copy(update={"target_relative_error": None,
                                     "max_seconds": min(query.max_seconds or PILOT_SECONDS, PILOT_SECONDS)})
    return await _answer(request, "sync", _points_query, scene_id, pilot, request)


def _points_query(scene_id: str, query: IlluminanceQuery, request: Request) -> tuple:
    hub = _hub(request)
    if len(query.points) > hub.limits.max_points:
        raise TooLarge(f"{len(query.points)} points asked; this service answers at most {hub.limits.max_points} "
                       f"per query", limit=hub.limits.max_points)
    asked = request_query(hub.limits, query)
    points = np.asarray(query.points, dtype=np.float64)
    normals = np.asarray(query.normals, dtype=np.float64)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    prepared = hub.prepare(scene_id)
    radius = query.radius if query.radius is not None else units.DEFAULT_RADIUS_M
    warnings = units.far_warnings(prepared.live, [(f"points[{k}]", p) for k, p in enumerate(query.points)]
                                  + units.light_positions(prepared.live))
    hub.check_query(prepared, asked)

    def work(progress: Any = None, cancel: Any = None) -> dict[str, Any]:
        payload = hub.run_points(prepared, points, normals, query.radius, asked, progress, cancel)
        _targeted(payload, query.cost_targets)
        payload.update(radius=radius)
        if warnings:
            payload["warnings"] = warnings + payload.get("warnings", [])
        payload["current"] = hub.is_current(scene_id, prepared.generation)
        return payload

    return ("illuminance", scene_id, prepared, work, asked.budget, {"generation": prepared.generation,
                                                                  "points": len(points)})


@router.post("/scenes/{scene_id}/sensors/{sensor_id}/simulate", response_model=SensorPublic,
             responses={202: {"model": JobAccepted}, 413: {}, 503: {}})
async def simulate_sensor(scene_id: SceneId, sensor_id: ItemId, request: Request, query: SensorSimulate | None = None,
                          mode: Mode = "sync") -> Any:
    """Trace photons for one sensor; a grid's result is kept for `map.png` until the scene changes."""
    return await _answer(request, mode, _sensor_query, scene_id, sensor_id, query or SensorSimulate(), request)


def _sensor_query(scene_id: str, sensor_id: str, query: SensorSimulate, request: Request) -> tuple:
    hub = _hub(request)
    asked = request_query(hub.limits, query)

    def sized(live: Any) -> None:   # refused before anything is built
        sensor = find_sensor(live, sensor_id)
        kind_of(sensor).sized(sensor, hub.limits)

    prepared = hub.prepare(scene_id, sized)   # the one read of the scene's state
    sensor = find_sensor(prepared.live, sensor_id)  # the sensor in the snapshot the query runs on
    map_url = str(request.url_for("sensor_map", scene_id=scene_id, sensor_id=sensor_id).path)
    image_url = str(request.url_for("sensor_image_exr", scene_id=scene_id, sensor_id=sensor_id).path)
    warnings = units.far_warnings(prepared.live, units.sensor_positions(prepared.live, [sensor_id])
                                  + units.light_positions(prepared.live))
    hub.check_query(prepared, asked)

    answers = kind_of(sensor).ANSWER.model_fields   # what this kind's answer holds
    paths = ({n["uuid"]: n["path"] for n in request.app.state.manager.nodes(scene_id)}
             if "instances" in answers else {})

    def work(progress: Any = None, cancel: Any = None) -> dict[str, Any]:
        payload = hub.run_grid(prepared, sensor, asked, progress, cancel)
        for part in payload.get("instances", ()):
            part["path"] = paths.get(part["node"])
        _targeted(payload, query.cost_targets)
        if "map_url" in answers:
            payload["map_url"] = map_url
        if "image_url" in answers:
            payload["image_url"] = image_url
        if warnings:
            payload["warnings"] = warnings + payload.get("warnings", [])
        return payload

    return "sensor", scene_id, prepared, work, asked.budget, {"generation": prepared.generation, "sensor": sensor_id}


@router.get("/scenes/{scene_id}/sensors/{sensor_id}/map.png", name="sensor_map",
            response_class=Response, responses={200: {"content": {"image/png": {}}}, 404: {}})
def sensor_map(scene_id: SceneId, sensor_id: ItemId, request: Request,
               vmax: Annotated[float | None, Query(gt=0.0, allow_inf_nan=False,
                                                   description="Top of the colour scale, lx (cd/m² for a "
                                                               "camera).")] = None,
               vmin: MapVmin = None, scale: MapScale = "zero",
               show: Annotated[Literal["lux", "colour"], Query(
                   description="`lux`: false colour by illuminance; `colour`: the light's own colour (CIE 1931 "
                               "chromaticity shown in sRGB, brightness by illuminance; needs a simulation that "
                               "observed the spectrum).")] = "lux") -> Response:
    """False-colour PNG of the grid sensor's latest result at the scene's current state (lx); of a camera's, its
    luminance with a cd/m² legend (log scale where the lit pixels span more than 100:1)."""
    map_range(vmin, vmax)
    hub = _hub(request)
    live = hub.live.get(scene_id)
    sensor = find_sensor(live, sensor_id)
    kind = kind_of(sensor)
    if "map_url" not in kind.ANSWER.model_fields:
        mapped = types_where(lambda k: "map_url" in k.ANSWER.model_fields)
        raise NotFound(f"sensor {sensor_id!r} is a {sensor.get('type')} sensor; maps exist for {mapped} sensors")
    if kind.QUANTITY == "luminance":
        return _camera_map(request, scene_id, sensor_id, vmax)
    result = hub.grid_result(scene_id, sensor_id)
    if result is None:
        raise NotFound(f"sensor {sensor_id!r} has no result for the scene as it is now (revision {live.revision}); "
                       f"POST /scenes/{scene_id}/sensors/{sensor_id}/simulate first", revision=live.revision)
    name = _sensor_name(request, scene_id, sensor_id)
    if show == "colour":
        if result.get("cie_xy") is None:
            raise NotFound(f"sensor {sensor_id!r} has no observed spectrum: POST /scenes/{scene_id}/sensors/"
                           f"{sensor_id}/simulate with \"observe\": [\"spectrum\"] first", revision=live.revision)
        xy = np.asarray([[[math.nan if c is None else c for c in cell] for cell in row] for row in result["cie_xy"]])
        png = colour_map_png(xy, result["lux"], result["origin"], result["u"], result["v"],
                             title=f"{name} — scene revision {result['revision']}, {result['photons']:,} photons")
        return Response(content=png, media_type="image/png",
                        headers={"X-Scene-Revision": str(result["revision"]), "Cache-Control": "no-store"})
    png = illuminance_map_png(result["lux"], result["origin"], result["u"], result["v"], stderr=result["stderr"],
                              title=f"{name} — scene revision {result['revision']}, {result['photons']:,} photons",
                              vmax=vmax, vmin=vmin, scale=scale)
    return Response(content=png, media_type="image/png",
                    headers={"X-Scene-Revision": str(result["revision"]), "Cache-Control": "no-store"})


def _camera_map(request: Request, scene_id: str, sensor_id: str, vmax: float | None) -> Response:
    from service.routes.images import camera_result

    result = camera_result(request, scene_id, sensor_id)
    name = _sensor_name(request, scene_id, sensor_id)
    png = luminance_map_png(result["luminance"], stderr=result["stderr"], vmax=vmax,
                            title=f"{name} — scene revision {result['revision']}, {result['photons']:,} paths")
    return Response(content=png, media_type="image/png",
                    headers={"X-Scene-Revision": str(result["revision"]), "Cache-Control": "no-store"})


@router.get("/scenes/{scene_id}/sensors/{sensor_id}/export", name="sensor_export", response_class=Response,
            responses={200: {"content": {"text/plain": {}}, "description": "The IES or EULUMDAT file."}, 404: {}})
def sensor_export(scene_id: SceneId, sensor_id: ItemId, request: Request,
                  format: Annotated[Literal["ies", "ldt"], Query(
                      description="`ies`: IES LM-63-2002; `ldt`: EULUMDAT.")] = "ies") -> Response:
    """A far-field sensor's latest result as a photometric file: IES LM-63-2002 (absolute photometry, the flux
    leaving the scene in `[_ABSOLUTELUMENS]`) or EULUMDAT (cd/klm of that flux, LORL 100 %), the type-C table as
    simulated (no symmetry assumed). 404 while the sensor has no result, 422 for a sensor of another kind."""
    from tracer.photometry.export import write_photometry

    hub = _hub(request)
    live = hub.live.get(scene_id)
    sensor = find_sensor(live, sensor_id)
    if kind_of(sensor).QUANTITY != "candela":
        lamps = types_where(lambda k: k.QUANTITY == "candela")
        raise Invalid(f"sensor {sensor_id!r} is a {sensor.get('type')} sensor; only {lamps} sensors export as IES "
                      f"or EULUMDAT")
    result = hub.far_result(scene_id, sensor_id)
    if result is None:
        raise NotFound(f"sensor {sensor_id!r} has no result yet: POST /scenes/{scene_id}/sensors/{sensor_id}/simulate "
                       f"first", revision=live.revision)
    name = _sensor_name(request, scene_id, sensor_id)
    notes = (f"scene {scene_id} revision {result['revision']}, {result['photons']} photons, flux "
             f"{result['flux_lm']:.6g} +- {result['flux_stderr']:.2g} lm")
    try:
        text = write_photometry(format, result["candela"], result["c_deg"], result["gamma_deg"], result["flux_lm"],
                                name=name, notes=notes)
    except ValueError as exc:   # nothing left the scene: no distribution to write
        raise Invalid(f"sensor {sensor_id!r}: {exc}") from exc
    stem = re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("._") or sensor_id
    return Response(content=text, media_type="text/plain; charset=utf-8",
                    headers={"X-Scene-Revision": str(result["revision"]), "Cache-Control": "no-store",
                             "Content-Disposition": f'attachment; filename="{stem}.{format}"'})


def _sensor_name(request: Request, scene_id: str, sensor_id: str) -> str:
    """The name the user gave the sensor (the live body drops it), else its id."""
    manager = getattr(request.app.state, "manager", None)
    try:
        name = manager.get_assignment(scene_id, "sensor", sensor_id)["body"].get("name")  # type: ignore[union-attr]
    except Exception:  # no manager, or no such method: the id will do
        name = None
    return str(name) if name else f"sensor {sensor_id}"


def _job_state(hub: SimulationHub, job_id: str) -> dict[str, Any]:
    try:
        state = hub.jobs.get(job_id)
    except JobNotFound as exc:
        raise NotFound(str(exc)) from exc
    return state


def _public(hub: SimulationHub, request: Request, state: dict[str, Any]) -> dict[str, Any]:
    generation = state.pop("generation", None)
    state["url"] = str(request.url_for("get_job", job_id=state["id"]).path)
    state["current"] = generation is not None and hub.is_current(state["scene_id"], generation)
    if state.get("result") is not None:
        state["result"] = {k: v for k, v in state["result"].items() if k != "current"}
    return state


@router.get("/jobs/{job_id}", name="get_job", response_model=JobPublic)
def get_job(job_id: JobId, request: Request) -> dict[str, Any]:
    """A job's status, progress (photons, worst relative error, seconds, seconds left) and result.

    ``current`` is false once the scene changed after the job started: the result still describes
    the revision it names, not the scene as it is now.
    """
    hub = _hub(request)
    return _public(hub, request, _job_state(hub, job_id))


@router.delete("/jobs/{job_id}", response_model=JobPublic)
def cancel_job(job_id: JobId, request: Request) -> dict[str, Any]:
    """Cancel a job: a queued one never starts, a running one stops after its current batch."""
    hub = _hub(request)
    try:
        state = hub.jobs.cancel(job_id)
    except JobNotFound as exc:
        raise NotFound(str(exc)) from exc
    return _public(hub, request, state)
