"""An element used through its tabulated BSDF by the REST API (issue 36): ``"model": "bsdf"`` tabulates it once for
the part's dielectric ior and keeps the table beside the element, answers name the model, a material change
tabulates again, and a model that cannot go is a 422 naming it with nothing changed."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from service_helpers import glb, make_client, node, uid

import tracer.elements.bsdf as bsdf
from tests.tracer.transport_scenes import box

DOTS = {"type": "microstructure", "feature": {"shape": "dome", "radius_mm": 0.3, "height_mm": 0.15},
        "layout": {"type": "grid", "pitch_mm": [1.0, 1.0]}}


@pytest.fixture
def client(tmp_path: Path, monkeypatch: Any) -> Any:
    monkeypatch.setattr(bsdf, "RAYS", 60)    # a coarse table: this checks the plumbing, test_bsdf_model the physics
    with make_client(tmp_path) as c:
        c.data_dir = tmp_path
        yield c


def _scene(client: Any) -> str:
    sid = client.post("/scenes", json={"name": "film"}).json()["id"]
    v, t = box([0, 0, 0], [20, 20, 2])
    gid, data = glb(v.astype(np.float32), t)
    client.put(f"/geometries/{gid}", content=data, headers={"content-type": "model/gltf-binary"})
    nodes = [node(uid(0), None, "root"), node(uid(1), uid(0), "plate", geometry=gid),
             node(uid(2), uid(0), "other", geometry=gid)]
    assert client.put(f"/scenes/{sid}/document", json={"base_revision": 0, "length_unit": "mm", "nodes": nodes}
                      ).status_code == 200
    assert client.put(f"/scenes/{sid}/materials/{uid(1)}", json={"type": "dielectric", "ior": 1.49}
                      ).status_code in (200, 201)
    return sid


def _beam_through(client: Any, sid: str) -> Any:
    """A grid cell under the plate, a normal beam onto it, and the cell simulated with 2000 forward photons."""
    sensor = client.post(f"/scenes/{sid}/sensors", json={
        "type": "grid", "origin": [0.0, 0.0, -0.001], "u": [0.02, 0, 0], "v": [0, 0.02, 0], "nu": 1, "nv": 1}
                         ).json()["id"]
    client.post(f"/scenes/{sid}/lights", json={"type": "collimated", "origin": [0.01, 0.01, 0.005],
                                               "direction": [0, 0, -1], "radius": 0.003, "illuminance_lx": 1000})
    return client.post(f"/scenes/{sid}/sensors/{sensor}/simulate", json={"max_photons": 2000, "seed": 1,
                                                                           "estimator": "forward"})


def test_a_bsdf_assignment_is_tabulated_once_beside_the_element_and_answers_name_it(client: Any) -> None:
    sid = _scene(client)
    eid = client.post("/elements", json=DOTS).json()["id"]
    r = client.post(f"/scenes/{sid}/elements", json={"element": eid, "node": uid(1), "facing": [0, 0, 1],
                                                     "model": "bsdf"})
    assert r.status_code == 201, r.text
    assert r.json()["model"] == "bsdf" and r.json()["applied"]
    tables = sorted(p.name for p in (client.data_dir / "elements").glob(f"{eid}.bsdf-*.npz"))
    assert tables == [f"{eid}.bsdf-1.49.npz"]
    a = _beam_through(client, sid)
    assert a.status_code == 200, a.text
    assert [e["model"] for e in a.json()["elements"]] == ["bsdf"]
    assert a.json()["lux"][0][0] > 0
    # another ior: another table; the first one stays in the library
    assert client.put(f"/scenes/{sid}/materials/{uid(1)}", json={"type": "dielectric", "ior": 1.59}
                      ).status_code in (200, 201)
    listed = client.get(f"/scenes/{sid}/elements").json()
    assert listed[0]["applied"] and listed[0]["model"] == "bsdf"
    assert len(list((client.data_dir / "elements").glob(f"{eid}.bsdf-*.npz"))) == 2


def test_a_model_that_cannot_go_is_a_422_naming_it_and_nothing_changes(client: Any) -> None:
    sid = _scene(client)
    eid = client.post("/elements", json=DOTS).json()["id"]
    points = client.post("/elements", json={**DOTS, "layout": {"type": "points", "uv_mm": [[2, 2], [5, 5]]}}
                         ).json()["id"]
    before = client.get(f"/scenes/{sid}").json()
    for body, words in (({"element": eid, "node": uid(2), "model": "bsdf"}, "model: a tabulated BSDF"),
                        ({"element": points, "node": uid(1), "model": "bsdf"}, "periodic"),
                        ({"element": eid, "node": uid(1), "model": "wave"}, "model")):
        r = client.post(f"/scenes/{sid}/elements", json={**body, "facing": [0, 0, 1]})
        assert r.status_code == 422 and words in r.text, (body, r.text)
    assert client.get(f"/scenes/{sid}/elements").json() == []
    assert client.get(f"/scenes/{sid}").json() == before


def test_every_answer_through_a_table_carries_its_measured_error_and_it_covers_the_tables_deviation(
        tmp_path: Path) -> None:
    """Issue 54, item 11: the table's deviation from the exact model, measured when it is made (probe beams on both
    sides, `tracer.elements.bsdf.model_error`), comes with every answer that uses it (a sensor's and an illuminance
    query's `elements[].model_error`), and it covers what the two models give here: a normal beam through the dotted
    plate onto a cell below it, the transmitted share of the beam through the table against the exact dots."""
    with make_client(tmp_path) as client:        # the library's own table (RAYS rays a bin), not a coarse one
        sid = _scene(client)
        eid = client.post("/elements", json=DOTS).json()["id"]
        put = client.post(f"/scenes/{sid}/elements", json={"element": eid, "node": uid(1), "facing": [0, 0, 1],
                                                           "model": "bsdf"}).json()
        sensor = client.post(f"/scenes/{sid}/sensors", json={
            "type": "grid", "origin": [0.0, 0.0, -0.001], "u": [0.02, 0, 0], "v": [0, 0.02, 0], "nu": 1, "nv": 1}
                             ).json()["id"]
        client.post(f"/scenes/{sid}/lights", json={"type": "collimated", "origin": [0.01, 0.01, 0.005],
                                                   "direction": [0, 0, -1], "radius": 0.003, "illuminance_lx": 1000})
        query = {"max_photons": 60_000, "estimator": "forward"}
        tabled = client.post(f"/scenes/{sid}/sensors/{sensor}/simulate", json={**query, "seed": 1}).json()
        (entry,) = tabled["elements"]
        error = entry["model_error"]
        assert entry["model"] == "bsdf" and set(error) == {"air", "solid"}
        for side in ("air", "solid"):
            e = error[side]
            assert e["probes"] == 144 and e["probe_rays"] == bsdf.PROBE_RAYS and 0 < e["stderr"] < 0.05
            assert abs(e["deviation"]) > 3 * e["stderr"]      # a real deviation, not noise: the bins are coarse
        points = client.post(f"/scenes/{sid}/illuminance", json={"points": [[0.01, 0.01, -0.001]],
                                                                 "normals": [[0, 0, 1]], "max_photons": 2000})
        assert points.status_code == 200 and points.json()["elements"][0]["model_error"] == error
        client.delete(f"/scenes/{sid}/elements/{put['id']}")
        assert client.post(f"/scenes/{sid}/elements", json={"element": eid, "node": uid(1), "facing": [0, 0, 1],
                                                            "model": "exact"}).status_code == 201
        exact = client.post(f"/scenes/{sid}/sensors/{sensor}/simulate", json={**query, "seed": 2}).json()
        assert "model_error" not in exact["elements"][0]
    flux = 1000.0 * np.pi * 0.003 ** 2
    share = [a["lux"][0][0] * 0.02 ** 2 / flux for a in (tabled, exact)]
    sigma = [a["stderr"][0][0] * 0.02 ** 2 / flux for a in (tabled, exact)]
    difference = share[0] - share[1]
    bound = abs(error["air"]["deviation"])
    assert abs(difference) <= bound + 4 * np.hypot(error["air"]["stderr"], np.hypot(*sigma)), (difference, error)


def test_physics_left_out_says_how_far_the_table_is_from_the_exact_dots(client: Any) -> None:
    """Over REST: ``physics_left_out: ["element_geometry"]`` on a scene whose element goes through its table gives
    the exact micro-geometry's lux minus the answer's, with its error bar, and leaves the assignment tabulated; an
    unknown name is a 422 naming the names it takes."""
    sid = _scene(client)
    eid = client.post("/elements", json=DOTS).json()["id"]
    assert client.post(f"/scenes/{sid}/elements", json={"element": eid, "node": uid(1), "facing": [0, 0, 1],
                                                        "model": "bsdf"}).status_code == 201
    sensor = client.post(f"/scenes/{sid}/sensors", json={
        "type": "grid", "origin": [0.0, 0.0, -0.001], "u": [0.02, 0, 0], "v": [0, 0.02, 0], "nu": 1, "nv": 1}
                         ).json()["id"]
    client.post(f"/scenes/{sid}/lights", json={"type": "collimated", "origin": [0.01, 0.01, 0.005],
                                               "direction": [0, 0, -1], "radius": 0.003, "illuminance_lx": 1000})
    ask = {"max_photons": 4000, "seed": 1, "estimator": "forward"}
    a = client.post(f"/scenes/{sid}/sensors/{sensor}/simulate", json={**ask, "physics_left_out": ["element_geometry"]})
    assert a.status_code == 200, a.text
    left = a.json()["physics_left_out"]["element_geometry"]
    assert left["ran"] and left["photons"] > 0 and left["stderr"][0][0] > 0
    assert np.isfinite(left["difference"][0][0])
    assert [e["model"] for e in a.json()["elements"]] == ["bsdf"]
    assert client.get(f"/scenes/{sid}/elements").json()[0]["model"] == "bsdf"
    bad = client.post(f"/scenes/{sid}/sensors/{sensor}/simulate", json={**ask, "physics_left_out": ["elements"]})
    assert bad.status_code == 422 and "element_geometry" in bad.text, bad.text


def test_a_density_map_is_tabulated_by_fill_level_over_rest(client: Any) -> None:
    """A density map of printed dots takes ``"model": "bsdf"`` (issue 53): its table is kept with one level per fill
    (`tracer.elements.bsdf.LEVELS`), answers go through it, and its measured error names the fill level where it is
    furthest off."""
    sid = _scene(client)
    printed = {"type": "microstructure", "feature": {"shape": "dome", "radius_mm": 0.3, "height_mm": 0.01},
               "material": {"type": "lambertian", "reflectance": 0.8},
               "layout": {"type": "density", "origin_mm": [0, 0], "size_mm": [20, 20], "fill": [[0.2, 0.7]],
                          "pitch_mm": 1.0}}
    eid = client.post("/elements", json=printed).json()["id"]
    r = client.post(f"/scenes/{sid}/elements", json={"element": eid, "node": uid(1), "facing": [0, 0, 1],
                                                     "model": "bsdf"})
    assert r.status_code == 201, r.text
    with np.load(client.data_dir / "elements" / f"{eid}.bsdf-1.49.npz") as kept:
        table = bsdf.Table.from_arrays(kept)
    assert table.levels == bsdf.LEVELS and table.cdf.shape == (bsdf.LEVELS * table.bins, table.bins)
    a = _beam_through(client, sid)
    assert a.status_code == 200, a.text
    (element,) = a.json()["elements"]
    assert element["model"] == "bsdf" and a.json()["lux"][0][0] > 0
    # the worst of the five levels and of the four fills halfway between them
    assert {side: err["fill"] in np.arange(9) / 8 for side, err in element["model_error"].items()} == {
        "air": True, "solid": True}
