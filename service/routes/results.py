"""Kept sensor results (issue 22, `service.results`): listed, read as JSON or CSV, drawn, and compared.

- ``GET /scenes/{id}/sensors/{sid}/results`` — the kept results, newest first (key, revision, when, photons,
  seconds, min/mean/max lux);
- ``GET /scenes/{id}/sensors/{sid}/results/{key}`` — one, with its cells (``?format=csv``: one row per cell);
- ``GET /scenes/{id}/sensors/{sid}/results/{key}/map.png`` — its false-colour map (grid sensors, cameras);
- ``GET /scenes/{id}/sensors/{sid}/difference?from=K1&to=K2`` — ``to − from`` per cell with the combined standard
  error (``?format=csv`` too), and ``…/difference.png`` its map.

Luminance meters and cameras are kept too (values in cd/m²: ``luminance``, ``min_luminance``…, a camera's per
pixel). A key is the scene revision ``R`` (the latest state kept at it) or ``R.k`` (the k-th state at revision R: an
assignment keeps the revision). The results outlive the sensor; a sensor that never had a kept result and is not
in the scene is a 404.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from fastapi import APIRouter, Path, Query, Request, Response
from pydantic import BaseModel, Field

from service.errors import NotFound
from service.kind_wire import SensorType
from service.maps import difference_map_png, illuminance_map_png, luminance_map_png
from service.results import KEY_PATTERN, ResultStore, difference, difference_csv, result_csv
from service.routes.deps import ItemId, MapScale, MapVmin, SceneId, map_range
from service.sensor_kinds import kind_of_type, types_where
from service.simulation import SimulationHub, Unavailable, hub_for

router = APIRouter(tags=["results"])

Key = Annotated[str, Path(pattern=KEY_PATTERN, description=(
    "A kept result: the scene revision R (the latest state kept at it), or R.k (the k-th state at revision R; an "
    "assignment keeps the revision). `…/results` lists them."))]
KeyQuery = Annotated[str, Query(pattern=KEY_PATTERN, description="A kept result's key: R or R.k (see `…/results`).")]
Format = Annotated[Literal["json", "csv"], Query(
    description="`csv`: one row per cell (i, j, the cell centre x_m, y_m, z_m in world metres, then the values).")]
CSV_OR_JSON: dict[int | str, dict[str, Any]] = {200: {"content": {"application/json": {}, "text/csv": {}}}, 404: {}}
PNG: dict[int | str, dict[str, Any]] = {200: {"content": {"image/png": {}}}, 404: {}}


class ResultSummary(BaseModel):
    """One kept result, without its cells."""

    key: str = Field(description="R.k: the scene revision and the state at it.")
    revision: int = Field(description="Scene revision the result describes.")
    edit: int = Field(description="Which state at that revision (0 first; an assignment makes the next).")
    created_at: str = Field(description="When it was computed (ISO 8601, UTC).")
    photons: int = Field(description="Photons (forward) or paths (backward) traced.")
    seconds: float = Field(description="Seconds the simulation took, s.")
    min_lux: float | None = Field(None, description="The smallest value, lx (sensors that answer illuminance).")
    mean_lux: float | None = Field(None, description="The mean value, lx.")
    max_lux: float | None = Field(None, description="The largest value, lx.")
    min_luminance: float | None = Field(None, description="The smallest value, cd/m² (luminance meters and "
                                                          "cameras).")
    mean_luminance: float | None = Field(None, description="The mean value, cd/m².")
    max_luminance: float | None = Field(None, description="The largest value, cd/m².")
    quantity: str | None = Field(None, description="`luminance` where the values are cd/m² (else lux).")
    type: SensorType | None = Field(None, description="The sensor's kind.")
    estimator: str | None = Field(None, description="The estimator that ran: `forward` or `backward`.")
    stop_reason: str | None = Field(None, description="Which rule stopped the run.")
    effects: list[str] | None = Field(None, description="The effect set the simulation ran with.")
    nu: int | None = Field(None, description="Grid: cells along u.")
    nv: int | None = Field(None, description="Grid: cells along v.")
    origin: list[float] | None = Field(None, description="Grid: corner of the rectangle, world metres.")
    u: list[float] | None = Field(None, description="Grid: edge along which i counts, m.")
    v: list[float] | None = Field(None, description="Grid: edge along which j counts, m.")
    center: list[float] | None = Field(None, description="Disk: its centre, world metres.")
    normal: list[float] | None = Field(None, description="Disk: the side it receives on, a unit vector.")
    radius: float | None = Field(None, description="Disk: its radius, m.")
    width: int | None = Field(None, description="Camera: pixels across.")
    height: int | None = Field(None, description="Camera: pixels down (row 0 the top).")
    position: list[float] | None = Field(None, description="Camera or meter: the eye, world metres.")
    look_at: list[float] | None = Field(None, description="Camera: a point on its line of sight, world metres.")
    fov_deg: float | None = Field(None, description="Camera: vertical field of view, degrees.")
    direction: list[float] | None = Field(None, description="Meter: where it looks.")
    aperture_deg: float | None = Field(None, description="Meter: its acceptance angle, degrees.")
    strategy: str | None = Field(None, description="Luminance: the estimator in words.")
    url: str | None = Field(None, description="This result's URL.")


class ResultList(BaseModel):
    """The kept results of one sensor."""

    scene_id: str = Field(description="The scene's id.")
    sensor: str = Field(description="The sensor's id.")
    keep: int = Field(description="How many results this service keeps per sensor (LUMENLINK_KEEP_RESULTS).")
    results: list[ResultSummary] = Field(description="Newest first.")


class ResultPublic(ResultSummary):
    """One kept result with its cells: for a grid, nv rows of nu cells (row j along v, column i along u)."""

    lux: list[Any] | None = Field(None, description="Illuminance, lx.")
    luminance: list[Any] | None = Field(None, description="Luminance, cd/m² (a camera: height rows of width "
                                                          "pixels, top row first).")
    stderr: list[Any] = Field(description="Standard error of each value, lx (cd/m² for luminance).")


class DifferencePublic(BaseModel):
    """``to − from`` per cell."""

    sensor: str = Field(description="The sensor's id.")
    from_: str = Field(alias="from", description="Key of the earlier result.")
    to: str = Field(description="Key of the later result.")
    type: str | None = Field(None, description="The sensor's kind: `grid` or `disk`.")
    quantity: str | None = Field(None, description="`luminance` where the values are cd/m² (else lux).")
    difference: list[Any] = Field(description="value(to) − value(from) per cell, lx (cd/m² for luminance).")
    stderr: list[Any] = Field(description="Combined standard error √(σ_from² + σ_to²) per cell, lx (cd/m²).")
    lux_from: list[Any] | None = Field(None, description="Illuminance of the earlier result per cell, lx.")
    lux_to: list[Any] | None = Field(None, description="Illuminance of the later result per cell, lx.")
    luminance_from: list[Any] | None = Field(None, description="Luminance of the earlier result per pixel, cd/m².")
    luminance_to: list[Any] | None = Field(None, description="Luminance of the later result per pixel, cd/m².")
    width: int | None = Field(None, description="Camera: pixels across.")
    height: int | None = Field(None, description="Camera: pixels down.")
    significance_sigmas: float = Field(description="A cell changed beyond noise where |difference| exceeds this many "
                                                   "standard errors.")
    summary: dict[str, Any] = Field(description="Cells, significant changes (increased, decreased), the largest rise "
                                                "and fall with where (world metres), the mean before and after, lx.")
    warnings: list[str] = Field(description="E.g. the sensor moved between the two: cells are paired by index.")
    nu: int | None = Field(None, description="Grid: cells along u.")
    nv: int | None = Field(None, description="Grid: cells along v.")
    origin: list[float] | None = Field(None, description="Grid (the later result's): corner, world metres.")
    u: list[float] | None = Field(None, description="Grid: edge along which the nu cells lie, m.")
    v: list[float] | None = Field(None, description="Grid: edge along which the nv cells lie, m.")
    center: list[float] | None = Field(None, description="Disk: its centre, world metres.")
    normal: list[float] | None = Field(None, description="Disk: the side it receives on, a unit vector.")
    radius: float | None = Field(None, description="Disk: its radius, m.")


def _store(request: Request) -> tuple[SimulationHub, ResultStore]:
    hub = hub_for(request.app)
    if hub.results is None:
        raise Unavailable("this service keeps no sensor results (it has no database engine)")
    return hub, hub.results


def _check_sensor(hub: SimulationHub, store: ResultStore, scene_id: str, sensor_id: str) -> None:
    """404 for an unknown scene, or a sensor that is neither in the scene nor has kept results."""
    hub.live.revision(scene_id)
    if store.count(scene_id, sensor_id) == 0 and not any(str(s.get("id")) == sensor_id
                                                           for s in hub.live.get(scene_id).sensors):
        raise NotFound(f"scene {scene_id} has no sensor {sensor_id} and no kept results of one")


def _get(request: Request, scene_id: str, sensor_id: str, key: str) -> dict[str, Any]:
    hub, store = _store(request)
    _check_sensor(hub, store, scene_id, sensor_id)
    return store.get(scene_id, sensor_id, key)


def _title(request: Request, scene_id: str, sensor_id: str) -> str:
    from service.routes.simulation import _sensor_name

    return _sensor_name(request, scene_id, sensor_id)


@router.get("/scenes/{scene_id}/sensors/{sensor_id}/results", response_model=ResultList,
            response_model_exclude_none=True)
def list_results(scene_id: SceneId, sensor_id: ItemId, request: Request) -> dict[str, Any]:
    """The sensor's kept results, newest first: key, revision, when, photons, seconds, min/mean/max lux."""
    hub, store = _store(request)
    _check_sensor(hub, store, scene_id, sensor_id)
    listed = store.list(scene_id, sensor_id)
    for r in listed:
        r["url"] = str(request.url_for("get_result", scene_id=scene_id, sensor_id=sensor_id, key=r["key"]).path)
    return {"scene_id": scene_id, "sensor": sensor_id, "keep": store.keep_count, "results": listed}


@router.get("/scenes/{scene_id}/sensors/{sensor_id}/results/{key}", name="get_result", response_model=ResultPublic,
            response_model_exclude_none=True, responses=CSV_OR_JSON)
def get_result(scene_id: SceneId, sensor_id: ItemId, key: Key, request: Request, format: Format = "json") -> Any:
    """One kept result with its cells; `?format=csv` for one row per cell (centre in world metres, lux, stderr)."""
    result = _get(request, scene_id, sensor_id, key)
    if format == "csv":
        return Response(result_csv(result), media_type="text/csv",
                        headers={"Content-Disposition": f'attachment; filename="{sensor_id}-{result["key"]}.csv"'})
    return result


@router.get("/scenes/{scene_id}/sensors/{sensor_id}/results/{key}/map.png", response_class=Response, responses=PNG)
def result_map(scene_id: SceneId, sensor_id: ItemId, key: Key, request: Request,
               vmax: Annotated[float | None, Query(gt=0.0, allow_inf_nan=False,
                                                   description="Top of the colour scale, lx.")] = None,
               vmin: MapVmin = None, scale: MapScale = "zero") -> Response:
    """False-colour PNG of a kept grid result."""
    map_range(vmin, vmax)
    result = _get(request, scene_id, sensor_id, key)
    kind = kind_of_type(result.get("type"))
    if "map_url" not in kind.ANSWER.model_fields:
        mapped = types_where(lambda k: "map_url" in k.ANSWER.model_fields)
        raise NotFound(f"result {result['key']} of sensor {sensor_id} is of a {result.get('type')} sensor; maps exist "
                       f"for {mapped} sensors")
    if kind.QUANTITY == "luminance":
        png = luminance_map_png(result["luminance"], stderr=result["stderr"], vmax=vmax,
                                title=f"{_title(request, scene_id, sensor_id)} — result {result['key']}, "
                                      f"{result['photons']:,} paths")
        return Response(png, media_type="image/png", headers={"X-Scene-Revision": str(result["revision"])})
    png = illuminance_map_png(result["lux"], result["origin"], result["u"], result["v"], stderr=result["stderr"],
                              title=f"{_title(request, scene_id, sensor_id)} — result {result['key']}, "
                                    f"{result['photons']:,} photons", vmax=vmax, vmin=vmin, scale=scale)
    return Response(png, media_type="image/png", headers={"X-Scene-Revision": str(result["revision"])})


def _difference(request: Request, scene_id: str, sensor_id: str, frm: str,
                to: str) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
    hub, store = _store(request)
    _check_sensor(hub, store, scene_id, sensor_id)
    before, after = store.get(scene_id, sensor_id, frm), store.get(scene_id, sensor_id, to)
    out = difference(before, after)
    out["sensor"] = sensor_id
    return out, before, after


From = Annotated[str, Query(alias="from", pattern=KEY_PATTERN, description="The earlier result's key (R or R.k).")]


@router.get("/scenes/{scene_id}/sensors/{sensor_id}/difference", response_model=DifferencePublic,
            response_model_exclude_none=True, response_model_by_alias=True, responses=CSV_OR_JSON)
def result_difference(scene_id: SceneId, sensor_id: ItemId, request: Request, frm: From, to: KeyQuery,
                      format: Format = "json") -> Any:
    """``to − from`` per cell, lx, with the combined standard error and where it changed beyond noise;
    `?format=csv`: ``i,j,x_m,y_m,z_m,lux_from,lux_to,difference_lux,stderr_lux``."""
    out = _difference(request, scene_id, sensor_id, frm, to)[0]
    if format == "csv":
        return Response(difference_csv(out), media_type="text/csv", headers={
            "Content-Disposition": f'attachment; filename="{sensor_id}-{out["from"]}-to-{out["to"]}.csv"'})
    return out


@router.get("/scenes/{scene_id}/sensors/{sensor_id}/difference.png", response_class=Response, responses=PNG)
def difference_map(scene_id: SceneId, sensor_id: ItemId, request: Request, frm: From, to: KeyQuery) -> Response:
    """The change between two kept grid results on a diverging scale; cells within noise (2σ) dotted."""
    out, before, after = _difference(request, scene_id, sensor_id, frm, to)
    if not kind_of_type(out.get("type")).DIFFERENCE_MAP:
        drawn = types_where(lambda k: k.DIFFERENCE_MAP)
        raise NotFound(f"sensor {sensor_id} is a {out.get('type')} sensor; difference maps exist for {drawn} sensors")
    png = difference_map_png(out["lux_from"], out["lux_to"], out["origin"], out["u"], out["v"],
                             stderr_before=before["stderr"], stderr_after=after["stderr"],
                             title=f"{_title(request, scene_id, sensor_id)} — change from {out['from']} to "
                                   f"{out['to']}")
    return Response(png, media_type="image/png")

