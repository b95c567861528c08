"""Nodes for people (issue 22): every node has a path, `?path=` and `?name=` find nodes, and wherever the API takes
a node UUID it takes the node's path too (resolved to the UUID when the call is made)."""

from __future__ import annotations

from urllib.parse import quote

import pytest
from service_helpers import UNKNOWN_ID, glb, grid_mesh, make_client, node, translation, uid

from service.paths import closest, occurrence_paths

PROBLEM = "application/problem+json"


def test_the_rule_first_bare_then_2_3_in_document_order_any_list_order() -> None:
    uuids = ["r", "a", "w1", "w2", "w3", "s", "r2"]
    parents = [None, "r", "a", "a", "a", "r", None]
    names = ["car", "axle", "wheel", "wheel", "wheel", "a/b", "car"]
    assert occurrence_paths(uuids, parents, names) == [
        "car", "car/axle", "car/axle/wheel", "car/axle/wheel[2]", "car/axle/wheel[3]", "car/a\u2215b", "car[2]"]
    # children listed before their parents: the same paths (ranks follow the order of same-named siblings)
    order = [2, 1, 5, 3, 0, 4, 6]
    got = occurrence_paths([uuids[i] for i in order], [parents[i] for i in order], [names[i] for i in order])
    assert dict(zip([uuids[i] for i in order], got, strict=True)) == \
        dict(zip(uuids, occurrence_paths(uuids, parents, names), strict=True))
    with pytest.raises(ValueError, match="cycle"):
        occurrence_paths(["x", "y"], ["y", "x"], ["x", "y"])


def test_closest_paths() -> None:
    paths = ["car", "car/body", "car/lamp/lens", "car/lamp/reflector", "car/axle/wheel", "car/axle/wheel[2]"]
    assert closest(paths, "car/lamp/lenz")[0] == "car/lamp/lens"
    assert "car/lamp/lens" in closest(paths, "car/lens")          # the right leaf in another assembly
    assert closest(paths, "zzzz") == []


@pytest.fixture
def world(tmp_path):
    body = glb(*grid_mesh(2))
    wheel = glb(*grid_mesh(3, z=1.0))
    with make_client(tmp_path) as c:
        for gid, data in (body, wheel):
            assert c.put(f"/geometries/{gid}", content=data).status_code in (200, 201)
        sid = c.post("/scenes", json={"name": "car"}).json()["id"]
        nodes = [node(uid(0), None, "car"), node(uid(1), uid(0), "body", geometry=body[0]),
                 node(uid(2), uid(0), "lamp/left", translation(0, 1, 0)),
                 node(uid(3), uid(2), "lens", geometry=wheel[0]),
                 node(uid(4), uid(0), "wheel", translation(1, 0, 0), geometry=wheel[0]),
                 node(uid(5), uid(0), "wheel", translation(2, 0, 0), geometry=wheel[0]),
                 node(uid(6), uid(0), "wheel", translation(3, 0, 0), geometry=wheel[0])]
        r = c.put(f"/scenes/{sid}/document", json={"base_revision": 0, "length_unit": "m", "nodes": nodes})
        assert r.status_code == 200, r.text
        yield c, sid


def state(c, sid) -> dict:
    return {k: c.get(f"/scenes/{sid}{k}").json() for k in ("", "/nodes", "/materials", "/lights", "/sensors")}


def test_every_node_carries_its_path_and_path_and_name_find_nodes(world) -> None:
    c, sid = world
    nodes = c.get(f"/scenes/{sid}/nodes").json()
    assert [n["path"] for n in nodes] == ["car", "car/body", "car/lamp\u2215left", "car/lamp\u2215left/lens",
                                          "car/wheel", "car/wheel[2]", "car/wheel[3]"]
    one = c.get(f"/scenes/{sid}/nodes", params={"path": "car/wheel[2]"})
    assert one.status_code == 200 and one.json()["uuid"] == uid(5) and one.json()["path"] == "car/wheel[2]"
    assert [n["uuid"] for n in c.get(f"/scenes/{sid}/nodes", params={"name": "wh*"}).json()] == \
        [uid(4), uid(5), uid(6)]
    assert [n["uuid"] for n in c.get(f"/scenes/{sid}/nodes", params={"name": "car/*/lens"}).json()] == [uid(3)]
    assert c.get(f"/scenes/{sid}/nodes", params={"name": "nothing*"}).json() == []

    miss = c.get(f"/scenes/{sid}/nodes", params={"path": "car/lens"})
    assert miss.status_code == 404 and miss.headers["content-type"].startswith(PROBLEM)
    assert miss.json()["did_you_mean"][0] == "car/lamp\u2215left/lens"
    assert "did you mean 'car/lamp\u2215left/lens'" in miss.json()["detail"]
    both = c.get(f"/scenes/{sid}/nodes", params={"path": "car", "name": "car"})
    assert both.status_code == 422 and "not both" in both.json()["detail"]
    bad = c.get(f"/scenes/{sid}/nodes", params={"path": "car\x01"})
    assert bad.status_code == 422 and "path" in bad.text


def test_a_path_works_wherever_a_node_uuid_does(world) -> None:
    c, sid = world
    lens = quote("car/lamp\u2215left/lens", safe="")
    r = c.put(f"/scenes/{sid}/materials/{lens}", json={"type": "dielectric", "ior": 1.5})
    assert r.status_code == 200, r.text
    assert r.json()["node"] == uid(3)                       # stored by the UUID the path named
    r = c.put(f"/scenes/{sid}/materials/car/wheel[3]", json={"type": "black"})   # unencoded works too
    assert r.status_code == 200 and r.json()["node"] == uid(6)
    assert {m["node"] for m in c.get(f"/scenes/{sid}/materials").json()} == {uid(3), uid(6)}
    assert c.delete(f"/scenes/{sid}/materials/{quote('car/wheel[3]', safe='')}").status_code == 204

    light = c.post(f"/scenes/{sid}/lights", json={"type": "point", "position": [0, 0, 0.1], "intensity_cd": 10,
                                                    "attached_to": "car/wheel[2]"})
    assert light.status_code == 201, light.text
    assert light.json()["body"]["attached_to"] == uid(5)
    area = c.post(f"/scenes/{sid}/lights", json={"type": "area", "node": "car/body", "exitance_lm_m2": 100})
    assert area.status_code == 201 and area.json()["body"]["node"] == uid(1)
    sensor = c.post(f"/scenes/{sid}/sensors", json={"type": "disk", "center": [0, 0, 1], "normal": [0, 0, 1],
                                                      "radius": 0.1, "attached_to": "car"})
    assert sensor.status_code == 201 and sensor.json()["body"]["attached_to"] == uid(0)
    up = c.put(f"/scenes/{sid}/materials/{uid(1).upper()}", json={"type": "black"})   # UUIDs as before
    assert up.status_code == 200 and up.json()["node"] == uid(1)


@pytest.mark.parametrize(("call", "status", "needle"), [
    (lambda c, sid: c.put(f"/scenes/{sid}/materials/car%2Fwheel%5B4%5D", json={"type": "black"}), 404,
     "car/wheel"),
    (lambda c, sid: c.post(f"/scenes/{sid}/lights", json={"type": "point", "position": [0, 0, 1],
                                                         "intensity_cd": 1, "attached_to": "car/lamp/lens"}),
     404, "car/lamp\u2215left/lens"),
    (lambda c, sid: c.post(f"/scenes/{sid}/lights", json={"type": "area", "node": "car/boddy",
                                                         "exitance_lm_m2": 1}), 404, "car/body"),
    (lambda c, sid: c.post(f"/scenes/{sid}/lights", json={"type": "point", "position": [0, 0, 1],
                                                         "intensity_cd": 1, "attached_to": ""}), 422, "attached_to"),
    (lambda c, sid: c.put(f"/scenes/{sid}/materials/car%09body", json={"type": "black"}), 422, "node"),
    (lambda c, sid: c.put(f"/scenes/{sid}/materials/{UNKNOWN_ID}", json={"type": "black"}), 404, UNKNOWN_ID),
])
def test_an_unknown_or_malformed_path_is_a_clear_4xx_and_changes_nothing(world, call, status, needle) -> None:
    c, sid = world
    before = state(c, sid)
    r = call(c, sid)
    assert r.status_code == status, r.text
    assert r.headers["content-type"].startswith(PROBLEM)
    assert needle in r.text
    if status == 404 and "did_you_mean" in r.json():
        assert needle in r.json()["did_you_mean"]
    assert state(c, sid) == before


def test_a_huge_polarizer_axis_is_a_direction_not_a_500(world) -> None:
    """Found by the fuzz once node paths let its bodies through: squaring 1.34e154 overflowed (OverflowError, 500)."""
    c, sid = world
    r = c.put(f"/scenes/{sid}/materials/car%2Fbody",
              json={"type": "polarizer", "axis": [0.0, 0.0, 1.3407807929942597e154]})
    assert r.status_code == 200, r.text
    assert c.put(f"/scenes/{sid}/materials/car%2Fbody", json={"type": "polarizer", "axis": [1e308, 1e308, 0]}
                 ).status_code == 200


def test_points_given_flat_get_one_message_that_says_the_form(world) -> None:
    """Six "valid tuple" errors said nothing of the form: the detail says it once, first (the errors stay listed)."""
    c, sid = world
    r = c.post(f"/scenes/{sid}/illuminance", json={"points": [0, 0, 1, 1, 0, 1], "normals": [[0, 0, 1], [0, 0, 1]]})
    assert r.status_code == 422 and r.headers["content-type"].startswith(PROBLEM)
    assert r.json()["detail"] == ("body.points: give a list of [x, y, z] triples, e.g. [[0, 0, 1], [1, 0, 1]], not a "
                                  "flat list of numbers")
    assert len(r.json()["errors"]) == 6
    r = c.post(f"/scenes/{sid}/illuminance", json={"points": [[0, 0, 1]], "normals": [[0, 0]]})
    assert r.status_code == 422 and "triples" not in r.json()["detail"] and "normals" in r.json()["detail"]
