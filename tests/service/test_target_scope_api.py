"""`target_scope` over REST (issue 22): a grid's target held on its lit cells stops on it where every cell's
cannot; a bad scope is a 422 naming the allowed ones; surface and far-field sensors refuse any scope but "worst"."""

from __future__ import annotations

import pytest
from service_helpers import glb, grid_mesh, make_client, node, translation, uid


@pytest.fixture(scope="module")
def strip(tmp_path_factory):
    client = make_client(tmp_path_factory.mktemp("scope"), max_photons=4_000_000)
    with client:
        sid = client.post("/scenes", json={"name": "strip"}).json()["id"]
        v, f = grid_mesh(n=2, size=30.0)
        gid, data = glb(v, f)
        client.put(f"/geometries/{gid}", content=data, headers={"content-type": "model/gltf-binary"})
        doc = {"base_revision": 0, "length_unit": "m", "source": {"name": "strip"},
               "nodes": [node(uid(0), None, "room"), node(uid(1), uid(0), "floor", translation(-5, -15, 0),
                                                          geometry=gid)]}
        assert client.put(f"/scenes/{sid}/document", json=doc).status_code == 200
        assert client.put(f"/scenes/{sid}/materials/{uid(1)}", json={"type": "black"}).status_code == 200
        client.post(f"/scenes/{sid}/lights", json={"type": "point", "position": [0, 0.5, 1.0], "intensity_cd": 100})
        grid = client.post(f"/scenes/{sid}/sensors", json={"type": "grid", "origin": [0, 0, 0], "u": [20, 0, 0],
                                                          "v": [0, 1, 0], "nu": 20, "nv": 1}).json()["id"]
        surface = client.post(f"/scenes/{sid}/sensors", json={"type": "surface", "node": "room/floor"}).json()["id"]
        yield client, sid, grid, surface


def test_a_grid_target_on_its_lit_cells_is_met_where_every_cell_cannot_be(strip):
    client, sid, grid, _ = strip
    body = {"target_relative_error": 0.05, "max_photons": 2_000_000, "seed": 3, "estimator": "forward"}
    lit = client.post(f"/scenes/{sid}/sensors/{grid}/simulate", json={**body, "target_scope": "lit"})
    every = client.post(f"/scenes/{sid}/sensors/{grid}/simulate", json=body)
    assert lit.status_code == every.status_code == 200, (lit.text, every.text)
    assert lit.json()["stop_reason"] == "target_relative_error" and every.json()["stop_reason"] == "max_photons"
    assert lit.json()["photons"] < every.json()["photons"]


def test_bad_scopes_are_refused(strip):
    client, sid, grid, surface = strip
    r = client.post(f"/scenes/{sid}/sensors/{grid}/simulate", json={"target_scope": "median", "max_photons": 1000})
    assert r.status_code == 422 and "target_scope" in r.text and "lit" in r.text
    r = client.post(f"/scenes/{sid}/sensors/{surface}/simulate", json={"target_scope": "lit", "max_photons": 1000})
    assert r.status_code == 422 and "target_scope 'worst'" in r.json()["detail"]
