"""What engineers compute from luminance, each value with its error bar (`tracer.photometry.glare`):

- ``GET /scenes/{id}/sensors/{sid}/ugr`` — the unified glare rating (CIE 117-1995) an observer at a camera's position
  sees looking along its line of sight, from the camera's latest image (the scene as it is now; 404 until it is
  simulated): source pixels above the line of sight at least ``threshold`` cd/m² (default 5 × the image's
  solid-angle-weighted mean), each weighted by its solid angle and its Luckiesh–Guth position index; the background
  luminance L_b is ``background`` where given, else the solid-angle-weighted mean of the other pixels. ``stderr``
  is first-order, from the pixels' standard errors (the sources' and the background's).
- ``POST /scenes/{id}/luminance/uniformity`` — a grid of luminance meters measured together (one run, one stop
  rule): the listed ``points``, the ``nine_points`` of a rectangle (the 9-point figure of a backlight or a
  display: the centres of its 3 × 3 division) or its ``thirteen_points`` (the SPWG pattern, 10 mm in from the
  edges), each seen by a meter ``distance`` metres back from it along
  ``direction``; the answer holds each meter's cd/m² ± stderr and the uniformity over them: min/max (U_d), min/mean
  (U₀), with their standard errors (the delta method, the smallest and largest meters held fixed).
- ``POST /scenes/{id}/luminance/conoscope`` — a conoscopic view of one point of a lit face: the luminance it shows
  against viewing angle, read by meters on a polar grid (``rings`` polar angles from the face's normal up to
  ``theta_max_deg``, ``azimuths`` azimuths from ``phi_zero``), measured together; ``?format=png`` draws it as a
  polar plot (what a conoscope shows), the on-axis luminance, the half-luminance angle (the view's spread,
  `tracer.sensors.luminance.half_angle`) and the flatness min/max with their error bars in its title
  (`tracer.sensors.luminance.conoscope`).
"""

from __future__ import annotations

import math
from typing import Annotated, Any, ClassVar, Literal

import numpy as np
from fastapi import APIRouter, Query, Request, Response
from pydantic import BaseModel, ConfigDict, Field, model_validator

from service.errors import Invalid, TooLarge
from service.routes.deps import ItemId, SceneId
from service.routes.images import camera_result
from service.routes.simulation import _answer, _targeted
from service.simulation import _refusals, hub_for, request_query
from service.simulation_wire import FiniteFloat, Mode, QueryBudget, Vec3
from tracer.errors import SimulationError
from tracer.photometry.glare import nine_points, thirteen_points, ugr_from_image, uniformity
from tracer.sensors.luminance import CONOSCOPE_AZIMUTHS, CONOSCOPE_MAX_THETA_DEG, CONOSCOPE_RINGS, conoscope_views

router = APIRouter(tags=["simulation"])
MAX_METERS = 1000
DEFAULT_DISTANCE_M = 0.5


class UgrPublic(BaseModel):
    """The UGR an observer at the camera sees along its line of sight."""

    sensor: str = Field(description="The camera's id.")
    revision: int = Field(description="Scene revision of the image it was computed from.")
    ugr: float = Field(description="Unified glare rating, 8 log₁₀(0.25/L_b Σ L² ω / p²).")
    stderr: float = Field(description="Its standard error (first order, from the pixels' standard errors).")
    background: float = Field(description="Background luminance L_b, cd/m².")
    background_stderr: float = Field(description="Its standard error, cd/m² (0 where the query gave it).")
    threshold: float = Field(description="Pixels at least this bright (cd/m²) and above the line of sight are "
                                         "sources.")
    source_pixels: int = Field(description="How many pixels were taken as sources.")
    sum: float = Field(description="Σ L² ω / p² over the source pixels, (cd/m²)² sr.")
    fov_deg: float = Field(description="The camera's vertical field of view, degrees: sources outside it are not "
                                       "counted.")
    position: list[float] = Field(description="The observer's eye (the camera's position), world metres.")
    look_at: list[float] = Field(description="A point on the line of sight, world metres.")
    method: str = Field(description="What was computed, in words.")


@router.get("/scenes/{scene_id}/sensors/{sensor_id}/ugr", response_model=UgrPublic, responses={404: {}})
def sensor_ugr(scene_id: SceneId, sensor_id: ItemId, request: Request,
               background: Annotated[float | None, Query(gt=0.0, allow_inf_nan=False, description=(
                   "Background luminance L_b, cd/m² (CIE 117: E_ind/π, the indirect vertical illuminance at the eye "
                   "over π); default: the solid-angle-weighted mean of the image's non-source pixels."))] = None,
               threshold: Annotated[float | None, Query(gt=0.0, allow_inf_nan=False, description=(
                   "Pixels at least this bright (cd/m²) above the line of sight are luminaires; default 5 × the "
                   "image's solid-angle-weighted mean luminance (evalglare's rule)."))] = None) -> dict[str, Any]:
    """UGR (CIE 117-1995) from the camera's latest image: the observer at its position, looking along its line of
    sight; 404 until the camera is simulated on the scene as it is now, 422 where no luminaire is seen."""
    result = camera_result(request, scene_id, sensor_id)
    try:
        out = ugr_from_image(np.asarray(result["luminance"], float), float(result["fov_deg"]),
                             stderr=np.asarray(result["stderr"], float), background=background, threshold=threshold)
    except ValueError as exc:
        raise Invalid(f"sensor {sensor_id!r}: {exc}") from exc
    return {**out, "sensor": sensor_id, "revision": int(result["revision"]), "fov_deg": float(result["fov_deg"]),
            "position": result["position"], "look_at": result["look_at"],
            "method": "CIE 117-1995 UGR over the image's pixels: each source pixel's luminance, solid angle and "
                      "Luckiesh–Guth position index (closed form, above the line of sight); first-order error"}


class NinePoints(BaseModel):
    """A rectangle origin + s u + t v (s, t in [0, 1]) whose 9-point figure is asked."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)
    FIELD: ClassVar[str] = "nine_points"   # the query's field, named in what is refused
    origin: Vec3 = Field(description="A corner of the lit area, world metres.")
    u: Vec3 = Field(description="One edge, m.")
    v: Vec3 = Field(description="The other edge, m.")

    @model_validator(mode="after")
    def _check(self) -> NinePoints:
        """A rectangle with an area: its points would otherwise fall on a line or on one point."""
        u, v, at = np.asarray(self.u, float), np.asarray(self.v, float), self.FIELD
        for name, edge in (("u", u), ("v", v)):
            if not np.any(edge):
                raise ValueError(f"{at}.{name} is the zero vector: give the rectangle's two edges, in metres")
        if np.linalg.norm(np.cross(u, v)) <= 1e-9 * np.linalg.norm(u) * np.linalg.norm(v):
            raise ValueError(f"{at}.u and {at}.v are parallel: the rectangle has no area; give two edges at an "
                             f"angle (perpendicular for a display's figure)")
        return self


class ThirteenPoints(NinePoints):
    """A rectangle origin + s u + t v whose 13-point figure (SPWG) is asked: points `inset` m in from its edges."""

    FIELD: ClassVar[str] = "thirteen_points"

    inset: Annotated[FiniteFloat, Field(gt=0.0)] = Field(
        default=0.01, description="How far the outer points stand in from each edge, m (10 mm in the SPWG pattern); "
                                  "less than half of each edge.")

    @model_validator(mode="after")
    def _inset(self) -> ThirteenPoints:
        """An inset that leaves the outer points inside the rectangle, on their own side of its middle."""
        half = 0.5 * min(math.hypot(*self.u), math.hypot(*self.v))
        if self.inset >= half:
            raise ValueError(f"thirteen_points.inset is {self.inset:g} m, at least half of the shorter edge "
                             f"({half:g} m): give an inset below it (10 mm on a display)")
        return self


class UniformityQuery(QueryBudget):
    """Body of ``POST /scenes/{id}/luminance/uniformity``: meters that look at points."""

    points: Annotated[list[Vec3], Field(min_length=1, max_length=MAX_METERS)] | None = Field(
        default=None, description="The points the meters look at, world metres (or `nine_points`).")
    nine_points: NinePoints | None = Field(
        default=None, description="The 9-point figure of a rectangle: the centres of its 3 × 3 division (at 1/6, "
                                  "1/2 and 5/6 of each edge), row by row along v.")
    thirteen_points: ThirteenPoints | None = Field(
        default=None, description="The 13-point figure of a rectangle (the SPWG notebook-panel pattern): rows at "
                                  "`inset` from each edge along v, at 1/4, 1/2 and 3/4; the edge and middle rows "
                                  "at `inset` from each side and the middle, the quarter rows at 1/4 and 3/4 along "
                                  "u; row by row along v.")
    direction: Vec3 = Field(description="The way every meter looks (towards the points), any non-zero length.")
    distance: Annotated[FiniteFloat, Field(gt=0.0)] = Field(
        default=DEFAULT_DISTANCE_M, description="How far each meter stands back from its point, m.")
    aperture_deg: Annotated[FiniteFloat, Field(gt=0.0, le=180.0)] = Field(
        default=1.0, description="Each meter's acceptance angle (its cone's full angle), degrees.")

    model_config = ConfigDict(json_schema_extra={"examples": [
        {"nine_points": {"origin": [-0.1, -0.06, 0.0], "u": [0.2, 0.0, 0.0], "v": [0.0, 0.12, 0.0]},
         "direction": [0.0, 0.0, -1.0], "distance": 0.5, "aperture_deg": 1.0, "max_seconds": 10.0}]})

    @model_validator(mode="after")
    def _check(self) -> UniformityQuery:
        if sum(x is not None for x in (self.points, self.nine_points, self.thirteen_points)) != 1:
            raise ValueError("give one of points, nine_points or thirteen_points")
        if math.hypot(*self.direction) == 0.0:
            raise ValueError("direction must not be the zero vector")
        meters_only(self)
        return self


def meters_only(query: QueryBudget) -> None:
    """A ValueError (a 422) for the query options luminance meters cannot answer."""
    if query.estimator == "forward":
        raise ValueError("estimator: luminance meters are answered by paths from the eye; the forward estimator "
                         "cannot (photons from the lights almost never enter a meter's cone); use 'backward' or "
                         "'auto'")
    for name in ("observe", "physics_left_out"):
        if getattr(query, name):
            raise ValueError(f"{name} is not available for luminance meters")
    if query.reference is not None:
        raise ValueError("reference is not available for luminance meters")


class Uniformity(BaseModel):
    """Uniformity of the readings; the standard errors by the delta method (null where a ratio is undefined)."""

    min: float = Field(description="The smallest reading, cd/m².")
    max: float = Field(description="The largest reading, cd/m².")
    mean: float = Field(description="The mean reading, cd/m².")
    min_max: float | None = Field(description="U_d = min/max.")
    min_max_stderr: float | None = Field(description="Its standard error.")
    min_mean: float | None = Field(description="U₀ = min/mean.")
    min_mean_stderr: float | None = Field(description="Its standard error.")


class MetersRun(BaseModel):
    """What an answer of luminance meters says of the run that measured them (`run_fields`)."""

    aperture_deg: float = Field(description="Each meter's acceptance angle, degrees.")
    photons: int = Field(description="Paths from the eye traced (all meters).")
    seconds: float = Field(description="Seconds the run took, s.")
    revision: int = Field(description="Scene revision the readings describe.")
    estimator: str = Field(description="The estimator that ran (`backward`: paths from the eye).")
    stop_reason: str = Field(description="Which rule stopped the run.")
    effects: list[str] = Field(description="The effect set the simulation ran with.")
    strategy: str = Field(description="The estimator in words.")
    unreachable: dict[str, Any] | None = Field(None, description="Light the paths from the eye cannot find here "
                                                                 "(then missing from the readings), or null.")
    cost: dict[str, Any] | None = Field(None, description="What tighter errors would cost (as for lux).")


def run_fields(res: Any, prepared: Any, aperture_deg: float) -> dict[str, Any]:
    """`MetersRun`'s fields of a meters' result `res` (`tracer.sensors.views.LuminanceResult`), and its compile
    seconds (for `cost`)."""
    return {"aperture_deg": aperture_deg, "photons": int(res.photons), "seconds": float(res.seconds),
            "compile_seconds": float(getattr(res, "compile_seconds", 0.0)), "revision": int(prepared.live.revision),
            "estimator": str(res.estimator), "stop_reason": str(res.stop_reason),
            "effects": sorted(str(e) for e in res.effects), "strategy": str(res.strategy),
            "unreachable": res.unreachable, "cost": res.cost}


class UniformityPublic(MetersRun):
    """The meters' readings and their uniformity."""

    figure: str = Field(description="`9-point` for nine_points, `13-point` for thirteen_points, else `points`.")
    points: list[list[float]] = Field(description="The points looked at, world metres.")
    positions: list[list[float]] = Field(description="Each meter's eye, world metres.")
    luminance: list[float] = Field(description="Each meter's reading, cd/m².")
    stderr: list[float] = Field(description="Its standard error, cd/m².")
    uniformity: Uniformity = Field(description="min/max (U_d) and min/mean (U₀) of the readings, with their "
                                               "standard errors; min, mean, max in cd/m².")


@router.post("/scenes/{scene_id}/luminance/uniformity", response_model=UniformityPublic,
             responses={200: {"content": {"image/png": {}}, "description": "With ?format=png: the points marked "
                                                                          "with their readings."},
                        202: {}, 413: {}, 503: {}})
async def luminance_uniformity(scene_id: SceneId, query: UniformityQuery, request: Request,
                               mode: Mode = "sync",
                               format: Annotated[Literal["json", "png"], Query(
                                   description="`png`: the points marked where they look, each with its reading, "
                                               "and the uniformity in the title (sync only).")] = "json",
                               ) -> Any:
    """Luminance meters looking at points (or the 9- or 13-point figure of a rectangle), measured together, and
    their uniformity (min/max, min/mean), each value with its standard error."""
    return await _answer_or_drawn(request, mode, format, "uniformity_png", _uniformity_query, scene_id, query)


async def _answer_or_drawn(request: Request, mode: str, format: str, draw: str, setup: Any, scene_id: str,
                           query: Any) -> Any:
    """The query's answer (`_answer`), or with ``format=png`` the picture `service.maps.<draw>` makes of it (at once:
    an async job's result is JSON, so png with mode=async is a 422)."""
    if format == "png" and mode == "async":
        raise Invalid("format=png answers at once: ask it with mode=sync (an async job's result is JSON)")
    payload = await _answer(request, mode, setup, scene_id, query, request)
    if format == "png":
        from service import maps  # matplotlib, loaded on the first picture

        return Response(getattr(maps, draw)(payload), media_type="image/png")
    return payload


#: what luminance meters take of a request beside its budget (they carry no Stokes vector and measure no left-out
#: physics; `tracer.sensors.luminance.meters`)
METER_FIELDS = ("seed", "estimator", "force_effects")


def _finite(d: dict[str, float]) -> dict[str, float | None]:
    """NaN (a ratio of nothing: every meter dark) as null."""
    return {k: (v if math.isfinite(v) else None) for k, v in d.items()}


def _uniformity_query(scene_id: str, query: UniformityQuery, request: Request) -> tuple:
    hub = hub_for(request.app)
    asked = request_query(hub.limits, query, METER_FIELDS)
    if query.nine_points is not None:
        n = query.nine_points
        pts, figure = nine_points(n.origin, n.u, n.v), "9-point"
    elif query.thirteen_points is not None:
        t = query.thirteen_points
        pts, figure = thirteen_points(t.origin, t.u, t.v, t.inset), "13-point"
    else:
        pts, figure = np.asarray(query.points, float), "points"
    d = np.asarray(query.direction, float)
    d = d / np.linalg.norm(d)
    eyes = pts - query.distance * d[None, :]
    prepared = hub.prepare(scene_id)
    hub.check_query(prepared, asked)

    def work(progress: Any = None, cancel: Any = None) -> dict[str, Any]:
        from tracer.sensors.luminance import meters

        with _refusals():
            res = meters(prepared.simulation, eyes, np.tile(d, (len(pts), 1)), query.aperture_deg, query=asked,
                         progress=progress, cancel=cancel)
        lum, err = np.asarray(res.luminance, float), np.asarray(res.stderr, float)
        payload = {"figure": figure, "points": pts.tolist(), "positions": eyes.tolist(), "luminance": lum.tolist(),
                   "stderr": err.tolist(), "uniformity": _finite(uniformity(lum, err)),
                   **run_fields(res, prepared, query.aperture_deg)}
        _targeted(payload, query.cost_targets)
        payload["current"] = hub.is_current(scene_id, prepared.generation)
        return payload

    return ("uniformity", scene_id, prepared, work, asked.budget, {"generation": prepared.generation,
                                                                 "points": len(pts)})


class ConoscopeQuery(QueryBudget):
    """Body of ``POST /scenes/{id}/luminance/conoscope``: a polar grid of meters looking at one point."""

    point: Vec3 = Field(description="The point of the lit face looked at, world metres.")
    normal: Vec3 = Field(description="The face's normal towards the viewer (any non-zero length): θ = 0.")
    theta_max_deg: Annotated[FiniteFloat, Field(gt=0.0, le=CONOSCOPE_MAX_THETA_DEG)] = Field(
        default=80.0, description="The largest polar angle from the normal, degrees.")
    rings: Annotated[int, Field(ge=CONOSCOPE_RINGS[0], le=CONOSCOPE_RINGS[1])] = Field(
        default=9, description="Polar angles, evenly from 0 to theta_max_deg (one meter on the axis).")
    azimuths: Annotated[int, Field(ge=CONOSCOPE_AZIMUTHS[0], le=CONOSCOPE_AZIMUTHS[1])] = Field(
        default=12, description="Azimuths per ring, evenly from phi_zero (360°/azimuths apart).")
    phi_zero: Vec3 | None = Field(default=None, description="The direction of φ = 0, projected into the face's "
                                                            "plane (not along the normal); default any.")
    distance: Annotated[FiniteFloat, Field(gt=0.0)] = Field(
        default=DEFAULT_DISTANCE_M, description="How far each meter stands from the point, m.")
    aperture_deg: Annotated[FiniteFloat, Field(gt=0.0, le=180.0)] = Field(
        default=1.0, description="Each meter's acceptance angle (its cone's full angle), degrees.")

    model_config = ConfigDict(json_schema_extra={"examples": [
        {"point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0], "theta_max_deg": 80.0, "rings": 9, "azimuths": 12,
         "max_seconds": 10.0}]})

    @model_validator(mode="after")
    def _check(self) -> ConoscopeQuery:
        try:   # the tracer's own checks of the grid (a zero normal, a phi_zero along it), before any job starts
            conoscope_views(self.point, self.normal, self.theta_max_deg, self.rings, self.azimuths, self.distance,
                            self.phi_zero)
        except SimulationError as exc:
            raise ValueError(str(exc)) from exc
        meters_only(self)
        return self


class ConoscopePublic(MetersRun):
    """Luminance against viewing angle at one point, each reading with its standard error."""

    point: list[float] = Field(description="The point looked at, world metres.")
    normal: list[float] = Field(description="The face's unit normal (θ = 0).")
    phi_zero: list[float] = Field(description="The unit direction of φ = 0 in the face's plane.")
    theta_deg: list[float] = Field(description="The rings' polar angles from the normal, degrees.")
    phi_deg: list[float] = Field(description="The azimuths, degrees from phi_zero towards normal × phi_zero.")
    luminance: list[list[float]] = Field(description="cd/m², [ring][azimuth] (ring 0, the axis, one reading "
                                                     "repeated).")
    stderr: list[list[float]] = Field(description="Their standard errors, cd/m².")
    on_axis: float = Field(description="The luminance along the normal, cd/m².")
    on_axis_stderr: float = Field(description="Its standard error, cd/m².")
    flatness: Uniformity = Field(description="min/max and min/mean over the view's distinct readings, with their "
                                             "standard errors (1 for a Lambertian face evenly lit).")
    half_angle_deg: float | None = Field(description=(
        "The viewing-angle spread: the polar angle, degrees, at which the luminance averaged over each ring's "
        "azimuths first falls below half the on-axis value, interpolated between the rings around it; the view's "
        "largest angle where it never does (half_angle_within_view false: at least that wide); null for a view dark "
        "on its axis."))
    half_angle_stderr: float | None = Field(description="Its standard error, degrees (0 where not within the view).")
    half_angle_within_view: bool = Field(description="Whether the luminance falls to half within the view.")
    distance: float = Field(description="How far each meter stood from the point, m.")


PNG = {"content": {"image/png": {}}, "description": "With ?format=png: the view as a polar plot."}


@router.post("/scenes/{scene_id}/luminance/conoscope", response_model=ConoscopePublic,
             responses={200: PNG, 202: {}, 413: {}, 503: {}})
async def luminance_conoscope(scene_id: SceneId, query: ConoscopeQuery, request: Request, mode: Mode = "sync",
                              format: Annotated[Literal["json", "png"], Query(
                                  description="`png`: the answer drawn as a polar plot (sync only).")] = "json",
                              ) -> Any:
    """A conoscopic view: the luminance a point of a lit face shows against viewing angle (polar angle from its
    normal, azimuth), read by meters on a polar grid in one run, each value with its standard error; the on-axis
    luminance, the half-luminance angle (the view's spread) and the flatness (min/max, min/mean) over the view."""
    return await _answer_or_drawn(request, mode, format, "conoscope_png", _conoscope_query, scene_id, query)


def _conoscope_query(scene_id: str, query: ConoscopeQuery, request: Request) -> tuple:
    hub = hub_for(request.app)
    count = 1 + (query.rings - 1) * query.azimuths
    if count > hub.limits.max_points:
        raise TooLarge(f"{query.rings} rings of {query.azimuths} azimuths are {count} meters; this service answers "
                       f"at most {hub.limits.max_points} per query: ask fewer rings or azimuths",
                       limit=hub.limits.max_points)
    asked = request_query(hub.limits, query, METER_FIELDS)
    prepared = hub.prepare(scene_id)
    hub.check_query(prepared, asked)

    def work(progress: Any = None, cancel: Any = None) -> dict[str, Any]:
        from tracer.sensors.luminance import conoscope, half_angle

        with _refusals():
            views, res = conoscope(prepared.simulation, query.point, query.normal, query.theta_max_deg, query.rings,
                                   query.azimuths, query.distance, query.aperture_deg, query.phi_zero, query=asked,
                                   progress=progress, cancel=cancel)
        lum, err = np.asarray(res.luminance, float), np.asarray(res.stderr, float)
        spread, spread_err, within = half_angle(views["theta_deg"], views["luminance"], views["stderr"])
        payload = {"point": list(query.point), "normal": views["normal"].tolist(),
                   "phi_zero": views["phi_zero"].tolist(), "theta_deg": views["theta_deg"].tolist(),
                   "phi_deg": views["phi_deg"].tolist(), "luminance": views["luminance"].tolist(),
                   "stderr": views["stderr"].tolist(), "on_axis": float(lum[0]), "on_axis_stderr": float(err[0]),
                   "flatness": _finite(uniformity(lum, err)), "distance": query.distance,
                   "half_angle_deg": None if math.isnan(spread) else spread,
                   "half_angle_stderr": None if math.isnan(spread_err) else spread_err,
                   "half_angle_within_view": within,
                   **run_fields(res, prepared, query.aperture_deg)}
        if query.cost_targets:   # of the meters' own readings, the axis once
            flat = {**payload, "luminance": lum.tolist(), "stderr": err.tolist()}
            _targeted(flat, query.cost_targets)
            payload["cost"] = flat["cost"]
        payload["current"] = hub.is_current(scene_id, prepared.generation)
        return payload

    return ("conoscope", scene_id, prepared, work, asked.budget, {"generation": prepared.generation, "points": count})
