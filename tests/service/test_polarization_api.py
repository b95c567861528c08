"""A polarized scene through the REST API (real app, real tracer): a polarizer sheet on a node, polarized lights,
Stokes vectors and the degree of polarization in the answers, and the 422s for bad polarization input.

The scene: the 4 m × 4 m floor (z = 0) is a polarizer sheet with its axis along the floor node's x; a collimated
beam of 100 lx falls straight down through it. Receivers under the floor face up: they see the light that passed.
"""

from __future__ import annotations

import pytest
from service_helpers import make_client, uid
from test_simulation_api import push_floor, query

BEAM = {"type": "collimated", "origin": [0.0, 0.0, 1.0], "direction": [0.0, 0.0, -1.0], "radius": 1.0,
        "illuminance_lx": 100.0}
POLARIZER = {"type": "polarizer", "axis": [1.0, 0.0, 0.0]}
BELOW = [[0.0, 0.0, -0.5], [0.3, 0.2, -0.5]]


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    client = make_client(tmp_path_factory.mktemp("polarized"), max_points=50, max_photons=4_000_000,
                         max_seconds=30.0)
    with client:
        sid = client.post("/scenes", json={"name": "polarizer floor"}).json()["id"]
        push_floor(client, sid, 0)
        r = client.put(f"/scenes/{sid}/materials/{uid(1)}", json=POLARIZER)
        assert r.status_code == 200, r.text
        yield client, sid


def _light(client, sid, **extra):
    r = client.post(f"/scenes/{sid}/lights", json={**BEAM, **extra})
    assert r.status_code == 201, r.text
    return r.json()["id"]


def test_a_polarizer_on_a_node_passes_half_of_unpolarized_light_polarized_along_its_axis(world):
    client, sid = world
    lid = _light(client, sid)
    try:
        r = client.post(f"/scenes/{sid}/illuminance", json=query(BELOW, radius=0.1, max_photons=200_000, seed=2,
                                                                observe=["stokes"], reference=[1, 0, 0]))
        assert r.status_code == 200, r.text
        a = r.json()
        assert "polarization" in a["effects"] and a["estimator"] == "forward"
        for lux, err, stokes, dop in zip(a["lux"], a["stderr"], a["stokes"], a["dop"], strict=True):
            assert abs(lux - 50.0) <= 4 * err, (lux, err)
            assert stokes[0] == lux and stokes[1] == pytest.approx(lux, rel=1e-9)   # along x: S1 = S0
            assert dop == pytest.approx(1.0, abs=1e-9)
        assert len(a["stokes_stderr"]) == 2 and len(a["stokes_stderr"][0]) == 4
        plain = client.post(f"/scenes/{sid}/illuminance", json=query(BELOW, radius=0.1, max_photons=20_000)).json()
        assert "stokes" not in plain and "dop" not in plain and "polarization" in plain["effects"]
        assert "polarization" in client.get(f"/scenes/{sid}").json()["effects"]
    finally:
        client.delete(f"/scenes/{sid}/lights/{lid}")


def test_light_polarized_across_the_axis_is_stopped_and_along_it_passes(world):
    client, sid = world
    for axis, expected in (([0.0, 1.0, 0.0], 0.0), ([1.0, 0.0, 0.0], 100.0)):
        lid = _light(client, sid, polarization={"type": "linear", "axis": axis})
        try:
            a = client.post(f"/scenes/{sid}/illuminance", json=query(BELOW[:1], radius=0.1, max_photons=50_000,
                                                                    observe=["stokes"])).json()
            assert abs(a["lux"][0] - expected) <= 4 * a["stderr"][0] and (a["lux"][0] == 0) == (expected == 0), a
            assert a["dop"][0] == (None if expected == 0.0 else pytest.approx(1.0))
        finally:
            client.delete(f"/scenes/{sid}/lights/{lid}")


@pytest.mark.parametrize(("path", "body", "match"), [
    ("materials", {"type": "polarizer", "axis": [0, 0, 0]}, "axis"),
    ("materials", {"type": "polarizer", "axis": [1, 0]}, "axis"),
    ("materials", {"type": "polarizer", "axis": [1, 0, 0], "extinction_ratio": 0.5}, "extinction_ratio"),
    ("materials", {"type": "polarizer"}, "axis"),
    ("materials", {"type": "retarder", "fast_axis": [1, 0, 0]}, "retardance_deg"),
    ("materials", {"type": "retarder", "fast_axis": [1, 0, 0], "retardance_deg": "90"}, "retardance_deg"),
    ("lights", {**BEAM, "polarization": {"type": "linear", "axis": [0, 0, 0]}}, "axis"),
    ("lights", {**BEAM, "polarization": {"type": "circular", "handedness": "up"}}, "handedness"),
    ("lights", {**BEAM, "polarization": {"type": "elliptic"}}, "polarization"),
])
def test_bad_polarization_input_is_a_422_that_changes_nothing(world, path, body, match):
    client, sid = world
    before = client.get(f"/scenes/{sid}").json()
    url = f"/scenes/{sid}/materials/{uid(1)}" if path == "materials" else f"/scenes/{sid}/lights"
    r = client.put(url, json=body) if path == "materials" else client.post(url, json=body)
    assert r.status_code == 422, r.text
    assert r.headers["content-type"].startswith("application/problem+json") and match in r.text, r.text
    assert client.get(f"/scenes/{sid}").json() == before
    assert [m["material"]["type"] for m in client.get(f"/scenes/{sid}/materials").json()] == ["polarizer"]


@pytest.mark.parametrize(("extra", "match"), [
    ({"observe": ["stokes"], "reference": [0, 0, 1]}, "lies along the normal"),
    ({"observe": ["stokes"], "reference": [0, 1]}, "reference"),
    ({"observe": ["polarisation"]}, "observe"),
])
def test_bad_stokes_queries_are_422s(world, extra, match):
    client, sid = world
    lid = _light(client, sid)
    try:
        r = client.post(f"/scenes/{sid}/illuminance", json=query(BELOW[:1], max_photons=1000, **extra))
        assert r.status_code == 422 and match in r.text, r.text
    finally:
        client.delete(f"/scenes/{sid}/lights/{lid}")
