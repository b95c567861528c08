"""Optical elements with an inside (docs/DESIGN.md "Optical elements with an inside"): the library, shared by every
scene, and their assignment to a part's support faces.

``POST /elements`` prepares a body once (the same body answers the same id, 200, preparing nothing);
``POST /scenes/{id}/elements`` puts one onto a node's triangles that face a direction (its frame), keeping the
node's instance, transform and material; ``DELETE`` takes it off. Bad input is a 422 naming the field, with
nothing changed: a pitch smaller than the feature, a fill outside [0, 1], an unknown element id, a support that
is not planar. A grating (``{"type": "grating"}``, docs/DESIGN.md "Elements with a wave solution inside") is solved
by RCWA in the request, its cost bounded first, and goes onto a face like any element, where a ray leaves in one of
its orders (`tracer.elements.diffraction`); ``GET /elements/{id}/orders.png`` plots its orders' efficiencies.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Body, Path, Query, Request, Response
from fastapi.responses import JSONResponse
from pydantic import BaseModel, ConfigDict, Field, model_validator

from service import paths
from service.errors import Invalid
from service.routes.deps import ItemId, Manager, SceneId
from service.simulation_wire import Mode

router = APIRouter(tags=["elements"])

ELEMENT_ID = r"^[0-9a-f]{64}$"

#: the examples /docs shows (the ceiling of the examples' room: its floor, dotted); tests/service/test_elements_api.py
#: checks that the id is the body's
DOTS_EXAMPLE = {"type": "microstructure", "feature": {"shape": "dome", "radius_mm": 0.25, "height_mm": 0.1},
                "relief": "bump", "layout": {"type": "grid", "pitch_mm": [1.0, 1.0]}}
DOTS_EXAMPLE_ID = "fed73e60f8cd2e2d004d1fe0e386581b233614a3bdd5c05733d00b083a36a5be"
ELEMENT_EXAMPLES = {
    "dots": {"summary": "domes 0.5 mm across on a 1 mm grid", "value": DOTS_EXAMPLE},
    "density": {"summary": "dots whose fill grows along u (a light guide's extraction pattern)", "value": {
        "type": "microstructure", "feature": {"shape": "dome", "radius_mm": 0.25, "height_mm": 0.1},
        "layout": {"type": "density", "origin_mm": [0, 0], "size_mm": [120, 80], "fill": [[0.1, 0.3, 0.6, 0.9]],
                   "seed": 1, "pitch_mm": 0.6}}},
    "prism film": {"summary": "90-degree prisms 50 um wide", "value": {
        "type": "microstructure", "feature": {"shape": "prism", "base_mm": 0.05, "apex_deg": 90},
        "layout": {"type": "grid", "pitch_mm": [0.05, 0.05]}}},
    "grating": {"summary": "a 1 um lamellar glass grating, solved by RCWA at 3 wavelengths and 3 angles", "value": {
        "type": "grating", "profile": {"shape": "lamellar", "fill": 0.5}, "period_um": 1.0, "depth_um": 0.3,
        "substrate_ior": 1.5, "wavelengths_nm": [450, 650], "wavelength_count": 3,
        "angles": {"polar_deg": [0, 20, 40], "azimuth_deg": [0]}, "orders": 6}},
    "wire grid": {"summary": "aluminium lines, 140 nm period, on glass (a wire-grid polarizer)", "value": {
        "type": "grating", "profile": {"shape": "lamellar", "fill": 0.5}, "period_um": 0.14, "depth_um": 0.15,
        "ridge": {"ior": [0.958, 6.69]}, "substrate_ior": 1.5, "wavelengths_nm": [450, 650], "wavelength_count": 3,
        "angles": {"polar_deg": [0, 30], "azimuth_deg": [0]}, "orders": 10}},
}
ElementId = Annotated[str, Path(pattern=ELEMENT_ID, description="a library element's id: 64 lowercase hex digits")]
ASSIGN_EXAMPLES = {"floor": {"summary": "the dots onto the floor's upward faces", "value": {
    "element": DOTS_EXAMPLE_ID, "node": "room/floor", "facing": [0, 0, 1]}}}


class ElementSummary(BaseModel):
    id: str = Field(description="the element's id: SHA-256 of its checked body (the same body, the same id)")
    type: str = Field("microstructure", description="the element's kind: 'microstructure' or 'grating'")
    features: int | None = Field(description="features prepared; null for a periodic layout (grid, hex), which "
                                             "holds as many as its support and takes no memory per feature")
    bytes: int = Field(description="memory of the prepared features (a grating: of its table of orders)")
    prepare_seconds: float = Field(description="seconds its preparation took (once, when it was first posted)")
    solver: str | None = Field(None, description="a grating: the wave solver that prepared its table (RCWA)")


class ElementDetail(ElementSummary):
    body: dict[str, Any] = Field(description="the checked body, with its defaults written out")


class ElementAssign(BaseModel):
    """An element onto a part: the triangles of `node` that face `facing` (its own frame), or its B-rep `faces`."""

    model_config = ConfigDict(extra="forbid")
    element: str = Field(pattern=ELEMENT_ID, description="a library element's id (POST /elements)")
    node: str = Field(min_length=1, max_length=4096, description="the part's node: UUID or path")
    facing: list[float] | None = Field(default=None, min_length=3, max_length=3,
                                       description="a direction in the node's frame: its triangles facing it "
                                                   "(within 1 degree) carry the element; they must be one plane")
    faces: list[int] | None = Field(default=None, min_length=1, description=(
        "B-rep face indices (the adapter pushes each triangle's face; cad_adapter.tessellate.face_table lists "
        "them): those faces' triangles carry the element, whatever tolerance the part was tessellated with"))

    model: Literal["exact", "bsdf"] | None = Field(default=None, description=(
        "'exact' (default): its micro-geometry traced; 'bsdf': its tabulated BSDF (in and out direction bins, "
        "computed once from the exact model for the part's dielectric ior and kept in the library beside it); "
        "periodic layouts (grid, hex)"))

    @model_validator(mode="after")
    def _one_support(self) -> ElementAssign:
        if (self.facing is None) == (self.faces is None):
            raise ValueError("give the support as 'facing' (a direction in the node's frame) or as 'faces', one "
                             "of the two")
        return self


class ElementAssignment(BaseModel):
    id: str = Field(description="the assignment's id, a UUID (DELETE takes the element off with it)")
    body: dict[str, Any] = Field(description="what was asked, the node as its UUID")
    orphaned: bool = Field(description="its node is not in the tree (it comes back with the node)")
    applied: bool = Field(description="the part carries it now")
    problem: str | None = Field(description="why it is not applied, where it is not (its node gone, or a push left "
                                            "the support unusable)")
    model: str = Field(description="the element's model answers use: 'exact' (its micro-geometry traced) or "
                                   "'bsdf' (its tabulated BSDF)")
    support: dict[str, Any] | None = Field(None, description=(
        "what carries it, where applied: the part's triangles selected, the support's size along u and v (mm) and "
        "its outward normal in the node's frame"))


@router.post("/elements", status_code=201, response_model=ElementSummary,
             responses={200: {"model": ElementSummary, "description": "the library already holds this body"},
                        202: {"description": "mode=async, a grating to solve: the preparation job"}})
def post_element(manager: Manager, request: Request, response: Response, body: Annotated[dict[str, Any], Body(
        description=("an element body: {type: microstructure, feature, relief, material, layout}, or {type: grating, "
                     "profile, period_um, depth_um, ridge, wavelengths_nm, orders, ...} (docs/DESIGN.md; a grating is "
                     "solved by RCWA, lit from both sides, its cost bounded first)"),
        openapi_examples=ELEMENT_EXAMPLES)], mode: Mode = "sync") -> Any:
    """Prepare an element into the library. A grating with ``mode=async`` (one not held yet) is solved as a job:
    202 at once, `GET /jobs/{id}` follows its progress (``fraction`` of the table points solved, ``points``, seconds
    and seconds left) and answers the element's summary as its result; its body is checked first (422, no job)."""
    library = manager.scenes.elements
    if mode == "async" and isinstance(body, dict) and body.get("type") == "grating":
        canon, known = library.check_grating(body)
        if known is not None:
            response.status_code = 200
            return known
        return _prepare_job(request, library, canon)
    summary, new = library.create(body)
    if not new:
        response.status_code = 200
    return summary


def _prepare_job(request: Request, library: Any, canon: dict) -> JSONResponse:
    """A grating's preparation as a job of no scene (``scene_id`` ""): progress by table point."""
    import time

    from service.routes.simulation import _accepted, _submit
    from service.simulation import hub_for
    from tracer.elements.grating_body import cost, table_points

    points = 2 * table_points(canon)

    def work(progress: Any = None, cancel: Any = None) -> dict[str, Any]:
        t0 = time.perf_counter()

        def report(fraction: float) -> None:
            if progress is not None:
                seconds = time.perf_counter() - t0
                progress(0, math.nan, seconds, fraction=fraction, points=round(fraction * points),
                         points_total=points, seconds_left=seconds * (1.0 - fraction) / max(fraction, 1e-9))

        return library.solve_grating(canon, report)

    hub = hub_for(request.app)
    job = _submit(hub, "prepare", "", 0, work, None, {"estimate_seconds": cost(canon), "points": points})
    return _accepted(request, job)


@router.get("/elements", response_model=list[ElementSummary])
def list_elements(manager: Manager) -> list[dict[str, Any]]:
    return manager.scenes.elements.list()


@router.get("/elements/{element_id}", response_model=ElementDetail)
def get_element(element_id: ElementId, manager: Manager) -> dict[str, Any]:
    return manager.scenes.elements.summary(element_id)


@router.post("/scenes/{scene_id}/elements", status_code=201, response_model=ElementAssignment)
def assign_element(scene_id: SceneId, body: Annotated[ElementAssign, Body(openapi_examples=ASSIGN_EXAMPLES)],
                   manager: Manager) -> dict[str, Any]:
    """Put a library element onto a part's faces. A part carries up to 8 elements on faces that share no triangle
    (dots underneath a light guide, prisms on top); faces another assignment of the node holds are a 409 naming it."""
    clean = body.model_dump(exclude_none=True)
    if not paths.is_uuid(clean["node"]):
        clean["node"] = paths.resolve(manager.nodes(scene_id), clean["node"], scene_id)
    else:
        clean["node"] = clean["node"].lower()
    return manager.assignments.add_element(scene_id, clean)


@router.get("/scenes/{scene_id}/elements", response_model=list[ElementAssignment])
def list_assigned(scene_id: SceneId, manager: Manager) -> list[dict[str, Any]]:
    return manager.assignments.list_elements(scene_id)


@router.get("/scenes/{scene_id}/elements/{item_id}", response_model=ElementAssignment)
def get_assigned(scene_id: SceneId, item_id: ItemId, manager: Manager) -> dict[str, Any]:
    return manager.assignments.get_element(scene_id, item_id)


class ElementSwitch(BaseModel):
    """The element an assignment carries from now on (the same node and faces)."""

    model_config = ConfigDict(extra="forbid")
    element: str = Field(pattern=ELEMENT_ID, description="a library element's id (a packed pattern, say)")


@router.put("/scenes/{scene_id}/elements/{item_id}", response_model=ElementAssignment)
def switch_assigned(scene_id: SceneId, item_id: ItemId, body: Annotated[ElementSwitch, Body(openapi_examples={
        "packed": {"summary": "the packed pattern in place of the one it was packed from",
                   "value": {"element": DOTS_EXAMPLE_ID}}})], manager: Manager) -> dict[str, Any]:
    """Switch an assignment to another library element in one call (after a pack: its result); only that part's
    element changes. 422 for an element the library lacks, nothing changed."""
    return manager.assignments.switch_element(scene_id, item_id, body.element)


class PackRequest(BaseModel):
    """Pack a density element on a scene's light guide: feedback on a grid of cells over its lit face."""

    model_config = ConfigDict(extra="forbid")
    scene: str = Field(min_length=1, max_length=200, description="the scene's id")
    assignment: str = Field(min_length=1, max_length=200, description="the element assignment that puts this "
                                                                      "element onto the guide's face")
    sensor: str = Field(min_length=1, max_length=200, description="a grid sensor over the lit face: its cells "
                                                                  "are the meters (illuminance, lx)")
    target: float = Field(0.8, description="the uniformity to reach, in (0, 1]")
    figure: str = Field("min_max", description="'min_max' (the 9-point figure on a 3 x 3 grid) or 'min_mean'")
    photons: int = Field(100_000, ge=1000, le=100_000_000, description="photons of the first measurement")
    max_photons: int = Field(1_600_000, ge=1000, le=100_000_000, description="the most photons of one "
                                                                             "measurement (they rise x4 as the "
                                                                             "map converges)")
    max_iterations: int = Field(10, ge=1, le=200, description="budget: measurements at most")
    max_seconds: float = Field(600.0, gt=0.0, le=86_400.0, description="budget: seconds")
    damping: float = Field(0.7, description="the multiplicative step's exponent, in (0, 1]")
    max_fill: float = Field(1.0, description="the largest fill a map cell may take, in (0, 1]")
    pitch_mm: float | None = Field(None, description="the lattice pitch (the minimum pitch between features); "
                                                     "default the element's")
    seed: int = Field(1, ge=0, lt=2 ** 31, description="photon seed (each iteration takes its own from it)")
    quantity: Literal["illuminance", "luminance"] = Field(
        "illuminance", description="what the grid's cells read: 'illuminance' (lx, forward photons) or 'luminance' "
                                   "(cd/m², as a display is judged: a viewer `distance` m in front of each cell, "
                                   "looking through it at the lit face along the grid's front normal u × v; paths "
                                   "from the eye)")
    distance: float = Field(0.5, gt=0.0, le=1000.0, description="with luminance: how far each meter stands in "
                                                                "front of its cell, m")
    aperture_deg: float = Field(1.0, gt=0.0, le=180.0, description="with luminance: each meter's acceptance "
                                                                   "angle (full cone), degrees")


PACK_EXAMPLES = {"guide": {"summary": "the demo guide's dots to 0.8 min/max on its 9-point grid", "value": {
    "scene": "<scene id>", "assignment": "<element assignment id>", "sensor": "<grid sensor id>", "target": 0.8,
    "max_iterations": 8}}}


@router.post("/elements/{element_id}/pack", status_code=202, responses={202: {"description": "the pack job"}})
def pack_element(element_id: ElementId, body: Annotated[PackRequest, Body(openapi_examples=PACK_EXAMPLES)],
                 manager: Manager, request: Request) -> JSONResponse:
    """Pack a density element against the scene's lit face, as a job (`GET /jobs/{id}`: iteration, uniformity ±
    error, seconds; `DELETE` cancels it and keeps what it measured). The result is a new element in the library
    with its history (`GET /elements/{id}/pack`) and `pack.png`; `PUT /scenes/{id}/elements/{aid}` switches the
    scene to it. 422 before any job for a target outside (0, 1], an element that is not a density layout, a face
    no light reaches."""
    from service import pack

    return _element_job(request, manager, "pack", pack.start, element_id, body)


def _element_job(request: Request, manager: Manager, kind: str, start: Any, element_id: str,
                 body: BaseModel) -> JSONResponse:
    """A pack or a design loop as a job: checked and set up by `start` (a 422 before any job), then queued."""
    from service.routes.simulation import _accepted, _submit
    from service.simulation import hub_for

    hub = hub_for(request.app)
    scene_id, revision, work, budget, meta = start(manager, hub, element_id, body.model_dump())
    return _accepted(request, _submit(hub, kind, scene_id, revision, work, budget, meta))


@router.get("/elements/{element_id}/pack")
def pack_record(element_id: ElementId, manager: Manager) -> Response:
    """How a packed element was found: target, why it stopped, every iteration (uniformity ± error, photons,
    seconds), the full-rebuild and per-iteration update times, the chosen map and what it measured."""
    return Response(manager.scenes.elements.record(element_id, ".pack.json"), media_type="application/json")


class DesignRequest(PackRequest):
    """A design loop over the element's parameters on a scene's light guide (`service.design`): a pack's request
    (the scene, the assignment, the grid, what its cells read; with ``pack_map``, the pack's own fields) with the
    numbers to vary and the objective."""

    parameters: list[dict[str, Any]] = Field(
        min_length=1, max_length=3, description="one to three numbers of the element's body to vary: {name, values} "
                                                "or {name, lo, hi, steps}; name as 'feature.height_mm', "
                                                "'feature.apex_deg', 'layout.pitch_mm[0]', 'material.reflectance'")
    objective: Literal["min_max", "min_mean", "mean", "half_angle"] = Field(
        "min_max", description="what the loop tunes: a uniformity of the grid's readings (min/max, min/mean), their "
                               "mean (on-axis luminance where the cells read luminance), or the viewing-angle spread "
                               "half_angle: the polar angle, degrees, where the luminance of the grid's centre falls "
                               "to half its on-axis value, read by a conoscopic view (0-80 degrees in 5-degree rings, "
                               "8 azimuths; the reading's distance and aperture)")
    goal: Literal["max", "min"] = Field(
        "max", description="raise the objective (max) or lower it (min: a narrower spread, for a brightness film)")
    pack_map: bool = Field(False, description="pack the density map before and after the sweep (with target, "
                                              "figure, max_iterations, ...); false keeps the map as it is")


DESIGN_EXAMPLES = {"guide": {"summary": "the dots' height for the most light out of the guide", "value": {
    "scene": "<scene id>", "assignment": "<element assignment id>", "sensor": "<grid sensor id>",
    "parameters": [{"name": "feature.height_mm", "lo": 0.05, "hi": 0.25, "steps": 5}], "objective": "mean"}},
    "film": {"summary": "a prism film's apex for the narrowest viewing-angle spread", "value": {
        "scene": "<scene id>", "assignment": "<element assignment id>", "sensor": "<grid sensor id>",
        "parameters": [{"name": "feature.apex_deg", "values": [80, 90, 100, 110]}], "objective": "half_angle",
        "goal": "min"}}}


@router.post("/elements/{element_id}/design", status_code=202, responses={202: {"description": "the design job"}})
def design_element(element_id: ElementId, body: Annotated[DesignRequest, Body(openapi_examples=DESIGN_EXAMPLES)],
                   manager: Manager, request: Request) -> JSONResponse:
    """Tune one to three numbers of the element against what the scene's lit face reads, as a job (`GET
    /jobs/{id}`: stage, candidate, objective ± error; `DELETE` cancels it and keeps the best read so far): every
    candidate read with the same random numbers, the best confirmed against the start on a fresh seed. The result is
    a new element in the library with its record (`GET /elements/{id}/design`); `PUT /scenes/{id}/elements/{aid}`
    switches the scene to it. 422 before any job for a parameter the element lacks, too many combinations, a face no
    light reaches."""
    from service import design

    return _element_job(request, manager, "design", design.start, element_id, body)


@router.get("/elements/{element_id}/design")
def design_record(element_id: ElementId, manager: Manager) -> Response:
    """How a designed element was found: the parameters' values, the baseline, every candidate (objective ± error,
    photons, seconds, or why it was refused), the packs, and the confirmation on a fresh seed."""
    return Response(manager.scenes.elements.record(element_id, ".design.json"), media_type="application/json")


@router.get("/elements/{element_id}/design.png", response_class=Response,
            responses={200: {"content": {"image/png": {}}}, 404: {}})
def design_png(element_id: ElementId, manager: Manager) -> Response:
    """Every candidate's objective with its error bar, the start's reading, the chosen one, and the confirmation on
    a fresh seed."""
    return Response(manager.scenes.elements.record(element_id, ".design.png"), media_type="image/png")


@router.get("/elements/{element_id}/pack.png", response_class=Response,
            responses={200: {"content": {"image/png": {}}}, 404: {}})
def pack_png(element_id: ElementId, manager: Manager) -> Response:
    """The density map, the map it measured over the face, and the uniformity against the iterations."""
    return Response(manager.scenes.elements.record(element_id, ".pack.png"), media_type="image/png")


@router.get("/elements/{element_id}/orders.png", response_class=Response,
            responses={200: {"content": {"image/png": {}}}, 404: {}, 422: {}})
def orders_png(element_id: ElementId, manager: Manager,
               polar_deg: Annotated[float | None, Query(description="one of the table's polar angles (deg); "
                                                                    "default its first")] = None,
               azimuth_deg: Annotated[float | None, Query(description="one of the table's azimuths (deg); default "
                                                                      "its first")] = None,
               lit_from: Annotated[Literal["ambient", "substrate"], Query(
                   description="the side the light comes from")] = "ambient") -> Response:
    """A grating's order efficiencies (unpolarized, transmitted and reflected, and their sum) against the
    wavelength, at one of its table's incidences (`service.grating_figure`); 422 for an element that is not a
    grating or an angle the table does not hold."""
    from service.grating_figure import orders_png as figure

    library = manager.scenes.elements
    if library.summary(element_id)["type"] != "grating":
        raise Invalid(f"element {element_id} is not a grating: only a grating has orders to plot")
    return Response(figure(library.get(element_id), polar_deg, azimuth_deg, lit_from), media_type="image/png")


@router.delete("/scenes/{scene_id}/elements/{item_id}", status_code=204)
def delete_assigned(scene_id: SceneId, item_id: ItemId, manager: Manager) -> Response:
    manager.assignments.delete_element(scene_id, item_id)
    return Response(status_code=204)
