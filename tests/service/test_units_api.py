"""Units stated and checked (issue 22, `service.units`): the receiver radius of a point query is stated in the
schema and echoed in the answer; lights, sensors and points far outside the model are warned about (naming the
document's unit and what the position would be in it), never refused.

The scene: a 1 m × 1 m floor drawn in millimetres (length_unit mm), the world in metres."""

from __future__ import annotations

import pytest
from service_helpers import glb, grid_mesh, make_client, node, uid

import tracer.simulate
from service import units

FAST = {"max_photons": 20_000, "seed": 1}


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    client = make_client(tmp_path_factory.mktemp("units"), max_points=10, max_photons=1_000_000, max_seconds=20.0)
    with client:
        sid = client.post("/scenes", json={"name": "mm-floor"}).json()["id"]
        v, f = grid_mesh(n=2, size=1000.0)          # a 1000 mm floor
        gid, data = glb(v, f)
        assert client.put(f"/geometries/{gid}", content=data,
                          headers={"content-type": "model/gltf-binary"}).status_code in (200, 201)
        doc = {"base_revision": 0, "length_unit": "mm", "source": {"name": "floor.step"},
               "nodes": [node(uid(0), None, "room"), node(uid(1), uid(0), "floor", geometry=gid)]}
        assert client.put(f"/scenes/{sid}/document", json=doc).status_code == 200
        yield client, sid


def points_query(client, sid: str, points: list, **extra) -> dict:
    r = client.post(f"/scenes/{sid}/illuminance",
                    json={"points": points, "normals": [[0, 0, 1]] * len(points), **FAST, **extra})
    assert r.status_code == 200, r.text
    return r.json()


def test_the_default_receiver_radius_is_stated_and_echoed(world) -> None:
    client, sid = world
    assert units.DEFAULT_RADIUS_M == tracer.simulate.DEFAULT_RADIUS
    schema = client.get("/openapi.json").json()["components"]["schemas"]["IlluminanceQuery"]
    assert "Default 0.05 m" in schema["properties"]["radius"]["description"]
    light = client.post(f"/scenes/{sid}/lights", json={"type": "point", "position": [0.5, 0.5, 0.5],
                                                      "intensity_cd": 100.0})
    assert light.status_code == 201 and light.json()["warnings"] == []
    a = points_query(client, sid, [[0.5, 0.5, 0.0]])
    assert a["radius"] == 0.05 and "warnings" not in a and a["lux"][0] > 0
    assert points_query(client, sid, [[0.5, 0.5, 0.0]], radius=0.002)["radius"] == 0.002
    assert client.delete(f"/scenes/{sid}/lights/{light.json()['id']}").status_code == 204


def test_far_positions_are_warned_about_naming_the_unit_never_refused(world) -> None:
    client, sid = world
    near = client.post(f"/scenes/{sid}/lights", json={"type": "point", "position": [0.09, 0.075, 0.5],
                                                     "intensity_cd": 100.0}).json()
    assert near["warnings"] == []
    # a point query in millimetres: answered, with a warning that says so
    a = points_query(client, sid, [[0.5, 0.5, 0.0], [500.0, 500.0, 0.0]])
    assert len(a["lux"]) == 2 and a["lux"][1] < 1e-6 * a["lux"][0]   # 100 cd seen from 700 m away
    (w,) = a["warnings"]
    assert w.startswith("points[1] at [500, 500, 0] m lies ") and "document unit is mm" in w
    assert "if it was meant in the document's unit (mm), it is [0.5, 0.5, 0] m" in w
    # a light in millimetres (the issue's [90, 75, 500]): added, with a warning; later answers repeat it
    r = client.post(f"/scenes/{sid}/lights", json={"type": "point", "position": [90, 75, 500], "intensity_cd": 100.0,
                                                  "name": "lamp"})
    assert r.status_code == 201, r.text
    far = r.json()
    (w,) = far["warnings"]
    assert w.startswith(f"light {far['id']} at [90, 75, 500] m lies ") and "its box [0, 0, 0] to [1, 1, 0] m" in w
    assert "diagonal 1.414 m" in w and "it is [0.09, 0.075, 0.5] m" in w
    assert far["id"] in {li["id"] for li in client.get(f"/scenes/{sid}/lights").json()}
    assert any(far["id"] in w for w in points_query(client, sid, [[0.5, 0.5, 0.0]])["warnings"])
    # a sensor in millimetres too, on adding and on simulating
    r = client.post(f"/scenes/{sid}/sensors", json={"type": "grid", "origin": [0, 0, 1], "u": [1000, 0, 0],
                                                   "v": [0, 1000, 0], "nu": 2, "nv": 2})
    assert r.status_code == 201
    sensor = r.json()
    assert len(sensor["warnings"]) == 1 and f"sensor {sensor['id']} at [500, 500, 1] m" in sensor["warnings"][0]
    r = client.post(f"/scenes/{sid}/sensors/{sensor['id']}/simulate", json=FAST)
    assert r.status_code == 200, r.text
    said = r.json()["warnings"]
    assert any(sensor["id"] in w for w in said) and any(far["id"] in w for w in said)
    for item in (("lights", far["id"]), ("lights", near["id"]), ("sensors", sensor["id"])):
        assert client.delete(f"/scenes/{sid}/{item[0]}/{item[1]}").status_code == 204


def test_a_scene_without_geometry_warns_of_nothing(world) -> None:
    client, _ = world
    sid = client.post("/scenes", json={"name": "empty"}).json()["id"]
    r = client.post(f"/scenes/{sid}/lights", json={"type": "point", "position": [1e6, 0, 0], "intensity_cd": 1.0})
    assert r.status_code == 201 and r.json()["warnings"] == []
