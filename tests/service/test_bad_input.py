"""Every bad input of issue 5 is refused with a problem+json that says what is wrong — and leaves the
scene exactly as it was (revision, nodes, assignments, tracer instances, stored files)."""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest
from service_helpers import UNKNOWN_ID, car_document, glb, grid_mesh, make_client, raw_glb, translation, uid

PROBLEM = "application/problem+json"


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    """One app with a pushed car, a material and a light; every test must leave it unchanged."""
    data = tmp_path_factory.mktemp("bad-input")
    with make_client(data, max_body_bytes=200_000) as client:
        body, wheel = glb(*grid_mesh(2)), glb(*grid_mesh(3, z=1.0))
        for gid, blob in (body, wheel):
            assert client.put(f"/geometries/{gid}", content=blob).status_code == 201
        sid = client.post("/scenes", json={"name": "car"}).json()["id"]
        doc = car_document(body[0], wheel[0])
        assert client.put(f"/scenes/{sid}/document", json=doc).status_code == 200
        assert client.put(f"/scenes/{sid}/materials/{uid(1)}", json={"type": "mirror", "reflectance": 0.9}).is_success
        assert client.post(f"/scenes/{sid}/lights", json={"type": "point", "position": [0, 0, 1],
                                                          "intensity_cd": 10}).is_success
        doc["base_revision"] = 1
        yield {"client": client, "scene": sid, "doc": doc, "data": data, "gids": (body[0], wheel[0])}


def snapshot(world) -> dict:
    c, sid = world["client"], world["scene"]
    live = c.app.state.live.get(sid)
    return {"summary": c.get(f"/scenes/{sid}").json(), "nodes": c.get(f"/scenes/{sid}/nodes").json(),
            "materials": c.get(f"/scenes/{sid}/materials").json(), "lights": c.get(f"/scenes/{sid}/lights").json(),
            "sensors": c.get(f"/scenes/{sid}/sensors").json(), "objects": c.get(f"/scenes/{sid}/objects").json(),
            "instances": sorted((i, live.tracer.instance_geometry(i), live.tracer.instance_transform(i).tolist())
                                for i in live.tracer.instances()),
            "files": sorted(p.name for p in (world["data"] / "meshes").iterdir()),
            "scenes": c.get("/scenes").json()}


@pytest.fixture
def unchanged(world):
    before = snapshot(world)
    yield
    assert snapshot(world) == before, "a refused request changed the scene"


def refused(r, status: int, contains: str = "") -> dict:
    assert r.status_code == status, r.text
    assert r.headers["content-type"] == PROBLEM
    body = r.json()
    assert body["status"] == status and body["title"] and body["type"] == "about:blank"
    assert contains.lower() in json.dumps(body).lower(), body
    return body


def put_doc(world, doc=None, raw: bytes | None = None):
    c, sid = world["client"], world["scene"]
    if raw is not None:
        return c.put(f"/scenes/{sid}/document", content=raw, headers={"content-type": "application/json"})
    return c.put(f"/scenes/{sid}/document", json=doc)


def mutated(world, fn) -> dict:
    doc = copy.deepcopy(world["doc"])
    doc["nodes"][2]["transform"] = translation(7, 0, 0)  # a real change, so only the defect can refuse it
    fn(doc)
    return doc


# ---------------------------------------------------------------- pushes


def test_malformed_json(world, unchanged) -> None:
    refused(put_doc(world, raw=b'{"base_revision": 1, "nodes": ['), 400, "json")


def test_wrong_types(world, unchanged) -> None:
    def bad(d):
        d["nodes"][1]["transform"] = "identity"
    body = refused(put_doc(world, mutated(world, bad)), 422, "transform")
    assert body["errors"][0]["loc"][:3] == ["nodes", "1", "transform"]


def test_wrong_number_of_transform_entries(world, unchanged) -> None:
    refused(put_doc(world, mutated(world, lambda d: d["nodes"][1].update(transform=[1.0] * 15))), 422, "transform")


@pytest.mark.parametrize("literal", ["NaN", "Infinity", "-Infinity", "1e999"])
def test_non_finite_numbers(world, unchanged, literal: str) -> None:
    text = json.dumps(mutated(world, lambda d: None))
    text = text.replace('"transform": [1.0, 0.0, 0.0, 7', f'"transform": [{literal}, 0.0, 0.0, 7', 1)
    assert literal in text
    refused(put_doc(world, raw=text.encode()), 422, "transform")


def test_singular_transform(world, unchanged) -> None:
    def bad(d):
        d["nodes"][4]["transform"] = [1.0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1]
    body = refused(put_doc(world, mutated(world, bad)), 422, "singular")
    assert body["problems"][0]["uuid"] == uid(10)


def test_projective_transform(world, unchanged) -> None:
    def bad(d):
        d["nodes"][4]["transform"] = [1.0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0.1, 0, 0, 1]
    refused(put_doc(world, mutated(world, bad)), 422, "affine")


def test_duplicate_uuids(world, unchanged) -> None:
    def bad(d):
        d["nodes"][5]["uuid"] = d["nodes"][4]["uuid"]
    body = refused(put_doc(world, mutated(world, bad)), 422, "duplicate")
    assert body["problems"] == [{"uuid": uid(10), "problem": "duplicate uuid"}]


def test_cycle(world, unchanged) -> None:
    def bad(d):
        d["nodes"][0]["parent"] = uid(10)  # car -> wheel0 -> axle -> car
    body = refused(put_doc(world, mutated(world, bad)), 422, "cycle")
    assert {p["uuid"] for p in body["problems"]} == {uid(0), uid(3), uid(10)}


def test_missing_parent(world, unchanged) -> None:
    refused(put_doc(world, mutated(world, lambda d: d["nodes"][4].update(parent=uid(999)))), 422, uid(999))


@pytest.mark.parametrize("gid", ["../../etc/passwd", "A" * 64, "a" * 63, "g" * 64, ""])
def test_geometry_id_that_is_not_64_hex(world, unchanged, gid: str) -> None:
    refused(put_doc(world, mutated(world, lambda d: d["nodes"][1].update(geometry=gid))), 422, "geometry")


def test_unknown_geometry_is_listed(world, unchanged) -> None:
    body = refused(put_doc(world, mutated(world, lambda d: d["nodes"][1].update(geometry="e" * 64))), 422, "e" * 64)
    assert body["missing"] == ["e" * 64]


@pytest.mark.parametrize("where", ["top", "node"])
def test_unknown_fields_are_rejected(world, unchanged, where: str) -> None:
    def bad(d):
        (d if where == "top" else d["nodes"][1])["colour"] = [1, 0, 0]
    refused(put_doc(world, mutated(world, bad)), 422, "colour")


def test_bad_uuid_and_unit(world, unchanged) -> None:
    refused(put_doc(world, mutated(world, lambda d: d["nodes"][1].update(uuid="not-a-uuid"))), 422, "uuid")
    refused(put_doc(world, mutated(world, lambda d: d.update(length_unit="furlong"))), 422, "length_unit")


def test_stale_base_revision(world, unchanged) -> None:
    body = refused(put_doc(world, mutated(world, lambda d: d.update(base_revision=0))), 409, "stale")
    assert body["current_revision"] == 1


def test_unknown_scene(world, unchanged) -> None:
    c = world["client"]
    refused(c.put("/scenes/00000000-0000-0000-0000-000000000000/document", json=world["doc"]), 404, "scene")
    refused(c.get(f"/scenes/{UNKNOWN_ID}"), 404)
    refused(c.post(f"/scenes/{UNKNOWN_ID}/lights", json={"type": "point", "position": [0, 0, 0], "flux_lm": 1}), 404)


def test_body_larger_than_the_limit(world, unchanged) -> None:
    big = mutated(world, lambda d: d["nodes"].extend(
        {"uuid": f"00000000-0000-0000-0000-{k:012d}", "parent": None, "name": "x" * 400,
         "transform": translation(k, 0, 0)} for k in range(600)))
    body = refused(put_doc(world, big), 413, "limit")
    assert body["limit"] == 200_000


def test_chunked_body_larger_than_the_limit(world, unchanged) -> None:
    c, sid = world["client"], world["scene"]

    def chunks():
        yield b'{"nodes": ['
        for _ in range(300):
            yield b" " * 1000

    body = refused(c.put(f"/scenes/{sid}/document", content=chunks()), 413)
    assert body["limit"] == 200_000   # the same problem as a body refused by its declared length


# ---------------------------------------------------------------- geometry uploads


def test_glb_whose_hash_does_not_match(world, unchanged) -> None:
    gid, _ = glb(*grid_mesh(2))
    _, other = glb(*grid_mesh(5))
    body = refused(world["client"].put(f"/geometries/{gid}", content=other), 400, "hash")
    assert body["actual"] != gid


def test_mesh_with_out_of_range_indices(world, unchanged) -> None:
    v, f = grid_mesh(6)
    f = f.copy()
    f[3, 1] = len(v) + 5
    refused(world["client"].put(f"/geometries/{'d' * 64}", content=raw_glb(v, f)), 422, "indices")


@pytest.mark.parametrize("data", [b"", b"hello", b"glTF" + b"\0" * 30])
def test_body_that_is_not_a_glb(world, unchanged, data: bytes) -> None:
    refused(world["client"].put(f"/geometries/{'d' * 64}", content=data), 422, "glb")


def test_mesh_with_non_finite_vertices(world, unchanged) -> None:
    v, f = grid_mesh(2)
    v[0, 0] = np.nan
    refused(world["client"].put(f"/geometries/{'d' * 64}", content=raw_glb(v, f)), 422, "finite")


@pytest.mark.parametrize("path", ["..%2F..%2Fservice.log", "ABC", "a" * 65, "%2e%2e"])
def test_geometry_path_tricks(world, unchanged, path: str) -> None:
    _, data = glb(*grid_mesh(2))
    r = world["client"].put(f"/geometries/{path}", content=data)
    assert r.status_code in (404, 422) and r.headers["content-type"] == PROBLEM
    r = world["client"].get(f"/geometries/{path}")
    assert r.status_code in (404, 422)
    assert not list(world["data"].glob("*.glb")) and not list(world["data"].parent.glob("*.glb"))


def test_missing_query_with_bad_ids(world, unchanged) -> None:
    refused(world["client"].post("/geometries/missing", json={"ids": ["../x"]}), 422, "ids")


# ---------------------------------------------------------------- assignments


def test_material_for_an_unknown_uuid(world, unchanged) -> None:
    c, sid = world["client"], world["scene"]
    refused(c.put(f"/scenes/{sid}/materials/{uid(999)}", json={"type": "black"}), 404, uid(999))


@pytest.mark.parametrize("material, field", [
    ({"type": "lambertian", "reflectance": 1.2}, "reflectance"),
    ({"type": "lambertian", "reflectance": -0.1}, "reflectance"),
    ({"type": "mirror", "reflectance": 3}, "reflectance"),
    ({"type": "dielectric", "ior": -1.5}, "ior"),
    ({"type": "dielectric", "ior": 1.5, "absorption_per_m": -1}, "absorption"),
    ({"type": "dielectric", "ior": 1.5, "g": 1.0}, "g"),
    ({"type": "mix", "diffuse": 0.7, "specular": 0.6}, "at most 1"),
    ({"type": "chrome", "reflectance": 0.5}, "chrome"),
    ({"type": "lambertian", "reflectance": 0.5, "roughness": 0.1}, "roughness"),
    ({"reflectance": 0.5}, "type"),
    ({"type": "dielectric", "ior": 1.5, "scattering_per_m": 1e10}, "scattering_per_m"),
    ({"type": "diffuser", "transmittance": 0.8, "reflectance": 0.3}, "transmittance + reflectance"),
    ({"type": "diffuser", "transmittance": True}, "transmittance"),
    ({"type": "diffuser", "reflectance": 0.1}, "transmittance"),
    ({"type": "microfacet", "alpha": 0.0, "reflectance": 0.9}, "alpha"),
    ({"type": "microfacet", "alpha": 0.1, "alpha_y": 2.0, "reflectance": 0.9}, "alpha_y"),
    ({"type": "microfacet", "alpha": 0.1, "axis": [0, 0, 0], "metal": [0.96, 6.69]}, "axis"),
    ({"type": "microfacet", "alpha": 0.1, "metal": [0.96, -1]}, "metal"),
    ({"type": "rough_dielectric", "ior": 1.5, "alpha": 0.0}, "alpha"),
    ({"type": "rough_dielectric", "alpha": 0.2}, "ior"),
    ({"type": "rough_dielectric", "ior": 1.5, "alpha": 0.1, "axis": [0, 0, 0]}, "axis"),
    ({"type": "rough_dielectric", "ior": 1.5}, "alpha"),
    ({"type": ["rough_dielectric"], "ior": 1.5}, "type"), ({"type": {"kind": "dielectric"}, "ior": 1.5}, "type"),
    ({"type": "dielectric", "ior": 1.5, "alpha": 5e-5}, "'alpha' must be 0 (a smooth surface) or at least"),
    ({"type": "dielectric", "ior": 1.5, "axis": [1, 0, 0]}, "give 'alpha' > 0 too"),
    ({"type": "dielectric", "ior": 1.5, "medium": {"type": "homogeneous", "g": -1.0}}, "g"),
    ({"type": "dielectric", "ior": 1.5, "medium": {"type": "fog"}}, "homogeneous"),
    ({"type": "dielectric", "ior": 1.5, "medium": {"absorption_per_m": 1.0}}, "type"),
    ({"type": "dielectric", "ior": 1.5, "medium": {"type": "homogeneous", "colour": 1}}, "colour"),
    ({"type": "dielectric", "ior": 1.5, "medium": "milky"}, "medium"),
    ({"type": "dielectric", "ior": 1.5, "medium": {"type": "homogeneous", "scattering_per_m": 2.0,
                                                   "particles": {"radius_um": 0.5, "ior": [1.59, 0.0],
                                                                 "number_per_m3": 1e15}}}, "not both"),
    ({"type": "dielectric", "ior": 1.5, "absorption_per_m": 1.0, "medium": {"type": "homogeneous"}},
     "not both"),
    ({"type": "measured_brdf", "table": {"theta_i_deg": [0], "theta_o_deg": [0, 90], "dphi_deg": [0, 180],
                                         "brdf": [[[0.4]]]}}, "table.brdf' reflects more than it receives"),
    ({"type": "measured_brdf", "table": "theta_i_deg 0\ntheta_o_deg 0 90\ndphi_deg 0 180\n-1\n"}, "table.brdf"),
])
def test_impossible_materials(world, unchanged, material: dict, field: str) -> None:
    c, sid = world["client"], world["scene"]
    refused(c.put(f"/scenes/{sid}/materials/{uid(2)}", json=material), 422, field)


def test_diffuser_is_a_material_of_the_api(world) -> None:
    """A kind added to the tracer (one module) is in the API with no service change: schema and assignment."""
    c, sid = world["client"], world["scene"]
    body = {"type": "diffuser", "transmittance": 0.8, "reflectance": 0.1}
    r = c.put(f"/scenes/{sid}/materials/{uid(2)}", json=body)
    assert r.status_code == 200, r.text
    assert r.json()["material"] == body
    assert "diffuser" in c.get("/openapi.json").text


@pytest.mark.parametrize("light, status, text", [
    ({"type": "point", "position": [0, 0, 0], "intensity_cd": 1, "attached_to": uid(999)}, 404, uid(999)),
    ({"type": "area", "node": uid(999), "exitance_lm_m2": 10}, 404, uid(999)),
    ({"type": "point", "position": [0, 0, 0]}, 422, "exactly one"),
    ({"type": "point", "position": [0, 0, 0], "intensity_cd": 1, "flux_lm": 2}, 422, "exactly one"),
    ({"type": "point", "position": [0, 0], "intensity_cd": 1}, 422, "position"),
    ({"type": "point", "position": [0, 0, 0], "intensity_cd": -1}, 422, "intensity"),
    ({"type": "spot", "position": [0, 0, 0], "direction": [0, 0, 0], "cone_deg": 30, "intensity_cd": 1}, 422,
     "non-zero"),
    ({"type": "spot", "position": [0, 0, 0], "direction": [0, 0, 1], "cone_deg": 30, "falloff_deg": 40,
      "intensity_cd": 1}, 422, "falloff"),
    ({"type": "collimated", "origin": [0, 0, 0], "direction": [0, 0, 1], "radius": 0, "illuminance_lx": 1}, 422,
     "radius"),
    ({"type": "collimated", "origin": [0, 0, 0], "direction": [0, 0, 1], "illuminance_lx": 1}, 422, "either"),
    ({"type": "collimated", "origin": [0, 0, 0], "direction": [0, 0, 1], "radius": 1, "width": 1, "height": 1,
      "illuminance_lx": 1}, 422, "either"),
    ({"type": "collimated", "origin": [0, 0, 0], "direction": [0, 0, 1], "width": 1, "illuminance_lx": 1}, 422,
     "either"),
    ({"type": "collimated", "origin": [0, 0, 0], "direction": [0, 0, 1], "width": 1, "height": 2, "up": [0, 0, 3],
      "illuminance_lx": 1}, 422, "parallel"),
    ({"type": "goniometric", "position": [0, 0, 0], "format": "ies", "data": "not a photometry file"}, 422, "ies"),
    ({"type": "goniometric", "position": [0, 0, 0], "format": "ies", "data": "x", "direction": [0, 0, -1],
      "c0": [0, 0, 5]}, 422, "parallel"),
    ({"type": "goniometric", "position": [0, 0, 0], "format": "ies", "data": "x", "c0": [0, 0, 0]}, 422,
     "non-zero"),
    ({"type": "laser", "position": [0, 0, 0]}, 422, "laser"),
    ({"type": "rayfile", "position": [0, 0, 0], "data": "0 0 0 0 0 1"}, 422, "data"),
    ({"type": "rayfile", "position": [0, 0, 0], "data": "0 0 0 0 0 0 1"}, 422, "zero direction"),
    ({"type": "rayfile", "position": [0, 0, 0], "data": "0 0 0 0 0 1 1", "units": "inch"}, 422, "units"),
    ({"type": "rayfile", "position": [0, 0, 0], "data": "0 0 0 0 0 1 1", "flux_lm": -1}, 422, "flux_lm"),
    ({"type": "rayfile", "data": "0 0 0 0 0 1 1"}, 422, "position"),
])
def test_bad_lights(world, unchanged, light: dict, status: int, text: str) -> None:
    c, sid = world["client"], world["scene"]
    refused(c.post(f"/scenes/{sid}/lights", json=light), status, text)


@pytest.mark.parametrize("sensor, status, text", [
    ({"type": "grid", "origin": [0, 0, 0], "u": [1, 0, 0], "v": [2, 0, 0], "nu": 2, "nv": 2}, 422, "parallel"),
    ({"type": "grid", "origin": [0, 0, 0], "u": [1, 0, 0], "v": [0, 1, 0], "nu": 0, "nv": 2}, 422, "nu"),
    ({"type": "disk", "center": [0, 0, 0], "normal": [0, 0, 1], "radius": -1}, 422, "radius"),
    ({"type": "disk", "center": [0, 0, 0], "normal": [0, 0, 1], "radius": 1, "attached_to": uid(999)}, 404,
     uid(999)),
])
def test_bad_sensors(world, unchanged, sensor: dict, status: int, text: str) -> None:
    c, sid = world["client"], world["scene"]
    refused(c.post(f"/scenes/{sid}/sensors", json=sensor), status, text)


@pytest.mark.parametrize("obj, status, text", [
    ({"geometry": "e" * 64}, 422, "not uploaded"),
    ({"geometry": "../x"}, 422, "geometry"),
    ({"geometry": "GID"}, 422, "geometry"),
    ("singular", 422, "singular"),
    ("attached", 404, uid(999)),
])
def test_bad_objects(world, unchanged, obj, status: int, text: str) -> None:
    c, sid = world["client"], world["scene"]
    if obj == "singular":
        obj = {"geometry": world["gids"][0], "transform": [0.0] * 15 + [1.0]}
    elif obj == "attached":
        obj = {"geometry": world["gids"][0], "attached_to": uid(999)}
    refused(c.post(f"/scenes/{sid}/objects", json=obj), status, text)


def test_deleting_unknown_assignments(world, unchanged) -> None:
    c, sid = world["client"], world["scene"]
    refused(c.delete(f"/scenes/{sid}/lights/{UNKNOWN_ID}"), 404)
    refused(c.delete(f"/scenes/{sid}/materials/{uid(5)}"), 404)
    refused(c.get(f"/scenes/{sid}/sensors/{UNKNOWN_ID}"), 404)


def test_unknown_route_and_method(world, unchanged) -> None:
    refused(world["client"].get("/nope"), 404)
    refused(world["client"].delete("/geometries/missing"), 405)


def test_a_rayfile_light_is_a_light_of_the_api(world) -> None:
    """A light kind added to the tracer (one module) is in the API with no service change."""
    c, sid = world["client"], world["scene"]
    r = c.post(f"/scenes/{sid}/lights", json={"type": "rayfile", "position": [0, 0, 1], "units": "mm",
                                               "data": "0 0 0 0 0 -1 1\n0.5 0 0 0 0.6 -0.8 1\n", "flux_lm": 10})
    assert r.status_code == 201, r.text
    assert c.delete(f"/scenes/{sid}/lights/{r.json()['id']}").status_code in (200, 204)


def test_a_measured_brdf_is_a_material_of_the_api(world) -> None:
    """Issue 38: a measured table (inline or as file text) is assigned through the API as it is."""
    c, sid = world["client"], world["scene"]
    table = {"theta_i_deg": [0.0, 60.0], "theta_o_deg": [0.0, 45.0, 90.0], "dphi_deg": [0.0, 180.0],
             "brdf": [[[0.1], [0.2]], [[0.2], [0.1]]]}
    for body in ({"type": "measured_brdf", "table": table},
                 {"type": "measured_brdf", "table": "theta_i_deg 0\ntheta_o_deg 0 90\ndphi_deg 0 180\n0.3\n"}):
        r = c.put(f"/scenes/{sid}/materials/{uid(2)}", json=body)
        assert r.status_code == 200, r.text
        assert r.json()["material"] == body
    assert "measured_brdf" in c.get("/openapi.json").text
