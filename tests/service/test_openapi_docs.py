"""The OpenAPI document as /docs and /redoc show it (issue 23): every request body has examples, each example is
valid (against the schema and against the service itself), every field says what it is (with its unit), and every
operation documents its errors as the problem+json actually sent.

The examples describe one scene (`service.schemas`: a room with a 4 m × 4 m floor at z = 0, a ceiling panel); the
service here holds that scene, built from the examples themselves, and each JSON body example is sent to it.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from pydantic import TypeAdapter
from service_helpers import glb, grid_mesh, make_client, node, translation

from service import optics, schemas
from service.routes.simulation import IlluminanceQuery, SensorSimulate
from service.simulation import Limits, resolve_budget

#: request bodies that have no example, and why
NO_EXAMPLE = {("put", "/geometries/{gid}"): "a binary GLB (its id is its SHA-256): no example fits in a text box",
              ("post", "/optical-files"): "a ray file's or a BRDF table's raw bytes (its id is its SHA-256)"}
#: component properties that may lack a description, and why (none left)
NO_DESCRIPTION: dict[str, str] = {}
#: what a valid example may answer, per operation (beyond 200/201): a second scene of the same name is a conflict
MAY_ALSO_ANSWER = {("post", "/scenes"): {409}}
SIMULATION = {"/scenes/{scene_id}/illuminance", "/scenes/{scene_id}/illuminance/plan",
              "/scenes/{scene_id}/sensors/{sensor_id}/simulate", "/scenes/{scene_id}/luminance/uniformity"}
#: examples that name ids only a run gives (an element assignment, a pack or design loop's scene and sensor): read by
#: their models
BY_MODEL = {"/elements/{element_id}/pack": "PackRequest", "/elements/{element_id}/design": "DesignRequest",
            "/scenes/{scene_id}/elements/{item_id}": "ElementSwitch"}
CEILING_PANEL = "6f1c9a52-3b7e-4d08-9e2a-51c4b7d3e003"


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> tuple[Any, dict[str, Any], str]:
    """A service holding the examples' scene: the scene, the floor mesh and the document of the examples, plus a
    ceiling panel for the area light; answers (client, OpenAPI document, scene id)."""
    client = make_client(tmp_path_factory.mktemp("openapi-docs"))
    spec = client.get("/openapi.json").json()

    def example(method: str, path: str) -> Any:
        return next(iter(spec["paths"][path][method]["requestBody"]["content"]["application/json"]["examples"]
                         .values()))["value"]

    created = client.post("/scenes", json=example("post", "/scenes"))
    assert created.status_code == 201, created.text
    sid = created.json()["id"]
    gid, data = glb(*grid_mesh(n=2, size=4.0))
    assert gid == schemas.EXAMPLE_FLOOR_GEOMETRY   # the examples name the mesh this test uploads
    assert client.put(f"/geometries/{gid}", content=data,
                      headers={"content-type": "model/gltf-binary"}).status_code == 201
    pushed = client.put(f"/scenes/{sid}/document", json=example("put", "/scenes/{scene_id}/document"))
    assert pushed.status_code == 200, pushed.text
    panel, panel_data = glb(*grid_mesh(n=1, size=1.0))
    assert client.put(f"/geometries/{panel}", content=panel_data,
                      headers={"content-type": "model/gltf-binary"}).status_code == 201
    doc = schemas.DOCUMENT_EXAMPLE
    nodes = doc["nodes"] + [node(CEILING_PANEL, doc["nodes"][0]["uuid"], "ceiling_panel",
                                 translation(-0.5, -0.5, 2.8), panel)]
    assert client.put(f"/scenes/{sid}/document", json={**doc, "base_revision": 1, "nodes": nodes}).status_code == 200
    return client, spec, sid


def _operations(spec: dict[str, Any]) -> list[tuple[str, str, dict[str, Any]]]:
    return [(method, path, op) for path, ops in spec["paths"].items() for method, op in ops.items()]


def _bodies(spec: dict[str, Any]) -> list[tuple[str, str, str, dict[str, Any]]]:
    return [(method, path, media_type, media) for method, path, op in _operations(spec)
            for media_type, media in op.get("requestBody", {}).get("content", {}).items()]


def _examples(spec: dict[str, Any]) -> list[tuple[str, str, str, Any]]:
    """(method, path, example name, value) of every JSON request body example."""
    return [(method, path, name, ex["value"]) for method, path, media_type, media in _bodies(spec)
            if media_type == "application/json" for name, ex in media["examples"].items()]


def test_every_request_body_has_an_example(served) -> None:
    _, spec, _ = served
    bodies = _bodies(spec)
    assert len(bodies) >= 10
    missing = [(m, p, t) for m, p, t, media in bodies if not media.get("examples") and (m, p) not in NO_EXAMPLE]
    assert missing == []
    # the union bodies offer one example per kind at least
    for path, kinds in (("/scenes/{scene_id}/lights", 5), ("/scenes/{scene_id}/sensors", 2),
                        ("/scenes/{scene_id}/materials/{node}", 8)):
        op = spec["paths"][path]["post" if "materials" not in path else "put"]
        assert len(op["requestBody"]["content"]["application/json"]["examples"]) >= kinds


def test_every_example_is_accepted_by_the_service(served) -> None:
    """Each example is sent where /docs offers it: no 422 (nor any other refusal); the simulation bodies, whose
    runs take seconds, go through the very models and budget check their routes use."""
    client, spec, sid = served
    grid = client.post(f"/scenes/{sid}/sensors", json=schemas.GRID_SENSOR_EXAMPLE)
    assert grid.status_code == 201, grid.text
    limits = Limits(max_points=100_000, max_photons=1_000_000_000, max_seconds=600.0)   # the service's defaults
    sent = 0
    for method, path, name, value in _examples(spec):
        if path in SIMULATION:
            from service.routes.glare import UniformityQuery

            model: Any = (SensorSimulate if "simulate" in path else UniformityQuery if "uniformity" in path
                          else IlluminanceQuery)
            query = model.model_validate(value)
            resolve_budget(limits, query.target_relative_error, query.max_seconds, query.max_photons)
            continue
        if path in BY_MODEL:
            from service.routes import elements

            getattr(elements, BY_MODEL[path]).model_validate(value)
            continue
        scene = sid
        if path == "/scenes/{scene_id}/document":   # as written (base_revision 0), to a new scene
            scene = client.post("/scenes", json={"name": f"document example {sent}"}).json()["id"]
        url = path.format(scene_id=scene, node="room/floor", sensor_id=grid.json()["id"])
        answer = client.request(method.upper(), url, json=value)
        assert answer.status_code in {200, 201} | MAY_ALSO_ANSWER.get((method, path), set()), (method, path, name,
                                                                                                answer.text)
        if path == "/scenes/{scene_id}/materials/{node}":   # the floor as the later examples expect it: white
            assert client.delete(url).status_code == 204
        sent += 1
    assert sent >= 20


def test_examples_match_the_schema_and_hold_no_null(served) -> None:
    jsonschema_rs = pytest.importorskip("jsonschema_rs")
    _, spec, _ = served
    components = {"components": spec["components"]}
    for method, path, _media_type, media in _bodies(spec):
        for name, ex in (media.get("examples") or {}).items():
            assert "null" not in json.dumps(ex["value"]), (method, path, name)   # optional fields are left out
            validator = jsonschema_rs.Draft202012Validator({**media["schema"], **components})
            errors = [e.message for e in validator.iter_errors(ex["value"])]
            assert errors == [], (method, path, name, errors)
    # the material, light and sensor kinds' own examples, as the models read them
    for union in (schemas.Light, schemas.Sensor, schemas.Material):
        adapter: TypeAdapter[Any] = TypeAdapter(union)
        for name, ex in adapter.json_schema(ref_template="#/components/schemas/{model}").get("$defs", {}).items():
            inner = TypeAdapter(optics.MediumWire) if name.endswith("Medium") else adapter   # a dielectric's medium
            for value in ex.get("examples", []):
                inner.validate_python(value)


def test_every_field_has_a_description() -> None:
    spec = make_client(Path(__import__("tempfile").mkdtemp(prefix="lumenlink-docs-"))).get("/openapi.json").json()
    schemas_ = dict(spec["components"]["schemas"])
    for method, path, _media_type, media in _bodies(spec):   # inline bodies (the pushed document)
        if "properties" in media["schema"]:
            schemas_[f"{method} {path}"] = media["schema"]
    assert len(schemas_) > 50
    missing = [f"{name}.{prop}" for name, schema in schemas_.items()
               for prop, sub in (schema.get("properties") or {}).items()
               if not str(sub.get("description") or "").strip() and f"{name}.{prop}" not in NO_DESCRIPTION]
    assert missing == []


@pytest.mark.parametrize(("model", "field", "unit"), [
    ("PointLight", "intensity_cd", "cd"), ("PointLight", "flux_lm", "lm"), ("PointLight", "flux_w", "W"),
    ("PointLight", "position", "m"), ("SpotLight", "cone_deg", "degrees"), ("CollimatedLight", "illuminance_lx", "lx"),
    ("AreaLight", "exitance_lm_m2", "lm/m²"), ("GridSensor", "u", "m"), ("DiskSensor", "radius", "m"),
    ("Lambertian", "reflectance", "fraction"), ("HomogeneousMedium", "absorption_per_m", "1/m"),
    ("Dielectric", "alpha", "dimensionless"),
    ("Dielectric", "ior", "dimensionless"), ("Retarder", "retardance_deg", "degrees"),
    ("IlluminanceQuery", "points", "metres"), ("IlluminanceQuery", "max_seconds", "s"),
    ("IlluminancePublic", "lux", "lx"), ("GridAnswer", "mean_lux", "lx"), ("FarFieldAnswer", "flux_lm", "lm"),
    ("CameraAnswer", "luminance", "cd/m²"), ("JobProgress", "seconds", "s"),
])
def test_descriptions_carry_units(served, model: str, field: str, unit: str) -> None:
    _, spec, _ = served
    assert unit in spec["components"]["schemas"][model]["properties"][field]["description"]


def test_every_operation_documents_its_errors_as_problem_json(served) -> None:
    _, spec, _ = served
    assert "Problem" in spec["components"]["schemas"]
    assert "HTTPValidationError" not in spec["components"]["schemas"]
    for method, path, op in _operations(spec):
        errors = {code: r for code, r in op["responses"].items() if code[:1] in "45"}
        assert {"401", "500"} <= set(errors), (method, path, sorted(errors))
        if op.get("parameters") or op.get("requestBody"):
            assert "422" in errors, (method, path)
        for code, response in errors.items():
            assert response["content"] == {"application/problem+json": {
                "schema": {"$ref": "#/components/schemas/Problem"}}}, (method, path, code)
            assert response.get("description"), (method, path, code)
