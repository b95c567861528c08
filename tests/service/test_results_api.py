"""Sensor results that outlive an edit (issue 22, `service.results`): kept per revision and assignment state,
bounded, listed, read as JSON and CSV, drawn, compared, and still there after a restart.

The scene of test_simulation_api: a black floor, a 100 cd point source 2 m above it, a 4 × 4 grid sensor."""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest
from service_helpers import UNKNOWN_ID, make_client, uid
from test_simulation_api import I_CD, H, push_floor

from service.errors import Invalid
from service.results import difference

PNG = b"\x89PNG\r\n\x1a\n"
KEEP = 3


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    data = tmp_path_factory.mktemp("results")
    client = make_client(data, max_points=50, max_photons=4_000_000, max_seconds=30.0, keep_results=KEEP)
    with client:
        scene = client.post("/scenes", json={"name": "floor"}).json()
        push_floor(client, scene["id"], 0)
        assert client.put(f"/scenes/{scene['id']}/materials/{uid(1)}", json={"type": "black"}).status_code == 200
        r = client.post(f"/scenes/{scene['id']}/lights",
                        json={"type": "point", "position": [0.0, 0.0, H], "intensity_cd": I_CD})
        assert r.status_code == 201, r.text
        grid = client.post(f"/scenes/{scene['id']}/sensors",
                           json={"type": "grid", "origin": [-0.5, -0.5, 0.0], "u": [1.0, 0.0, 0.0],
                                 "v": [0.0, 1.0, 0.0], "nu": 4, "nv": 4, "name": "centre"}).json()["id"]
        disk = client.post(f"/scenes/{scene['id']}/sensors",
                           json={"type": "disk", "center": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0],
                                 "radius": 0.05}).json()["id"]
        yield client, scene["id"], grid, disk, data


def simulate(client, sid: str, sensor: str, seed: int = 1) -> dict:
    r = client.post(f"/scenes/{sid}/sensors/{sensor}/simulate", json={"max_photons": 200_000, "seed": seed})
    assert r.status_code == 200, r.text
    return r.json()


def listed(client, sid: str, sensor: str) -> list[dict]:
    r = client.get(f"/scenes/{sid}/sensors/{sensor}/results")
    assert r.status_code == 200, r.text
    assert r.json()["keep"] == KEEP
    return r.json()["results"]


def test_results_are_kept_per_revision_and_state_and_compared(world) -> None:
    client, sid, grid, disk, data = world
    base = f"/scenes/{sid}/sensors/{grid}"
    assert listed(client, sid, grid) == []
    first = simulate(client, sid, grid)
    rev = first["revision"]
    (entry,) = listed(client, sid, grid)
    assert (entry["key"], entry["revision"], entry["edit"]) == (f"{rev}.0", rev, 0)
    assert entry["photons"] == first["photons"] and entry["seconds"] == first["seconds"]
    assert (entry["min_lux"], entry["mean_lux"], entry["max_lux"]) == (first["min_lux"], first["mean_lux"],
                                                                        first["max_lux"])
    assert entry["url"] == f"{base}/results/{rev}.0"

    kept = client.get(f"{base}/results/{rev}").json()   # R: the latest state at revision R
    assert kept["key"] == f"{rev}.0" and kept["lux"] == first["lux"] and kept["stderr"] == first["stderr"]
    rows = list(csv.DictReader(io.StringIO(client.get(f"{base}/results/{rev}.0", params={"format": "csv"}).text)))
    assert len(rows) == 16 and list(rows[0]) == ["i", "j", "x_m", "y_m", "z_m", "lux", "stderr_lux"]
    assert (float(rows[0]["x_m"]), float(rows[0]["y_m"]), float(rows[0]["z_m"])) == (-0.375, -0.375, 0.0)
    assert [float(r["lux"]) for r in rows] == np.ravel(first["lux"]).tolist()
    r = client.get(f"{base}/results/{rev}.0/map.png")
    assert r.status_code == 200 and r.content.startswith(PNG)
    for params in ({"scale": "data"}, {"vmin": 1.0, "vmax": 100.0}):   # scaled to the data, or to a stated range
        r = client.get(f"{base}/results/{rev}.0/map.png", params=params)
        assert r.status_code == 200 and r.content.startswith(PNG), r.text
    for params, words in (({"vmin": 5.0, "vmax": 5.0}, "vmin (5 lx) must be below vmax (5 lx)"),
                          ({"vmin": -1.0}, "greater than or equal to 0"), ({"scale": "log"}, "'zero' or 'data'")):
        for url in (f"{base}/results/{rev}.0/map.png", f"{base}/map.png"):
            r = client.get(url, params=params)
            assert r.status_code == 422 and words in r.text, (url, params, r.text)

    # the same state again replaces its result; an assignment (a second, equal light) keeps the revision and
    # makes the next state
    again = simulate(client, sid, grid, seed=2)
    assert [e["key"] for e in listed(client, sid, grid)] == [f"{rev}.0"]
    assert client.get(f"{base}/results/{rev}.0").json()["lux"] == again["lux"]
    second = client.post(f"/scenes/{sid}/lights", json={"type": "point", "position": [0.0, 0.0, H],
                                                        "intensity_cd": I_CD}).json()["id"]
    doubled = simulate(client, sid, grid)
    assert doubled["revision"] == rev
    assert [e["key"] for e in listed(client, sid, grid)] == [f"{rev}.1", f"{rev}.0"]
    assert client.get(f"{base}/results/{rev}").json()["key"] == f"{rev}.1"
    # the map of the scene as it is now changes; the kept one of rev.0 does not
    assert client.get(f"{base}/results/{rev}.0").json()["lux"] == again["lux"]

    d = client.get(f"{base}/difference", params={"from": f"{rev}.0", "to": f"{rev}.1"})
    assert d.status_code == 200, d.text
    diff = d.json()
    assert (diff["from"], diff["to"], diff["nu"], diff["nv"]) == (f"{rev}.0", f"{rev}.1", 4, 4)
    np.testing.assert_allclose(diff["difference"], np.subtract(doubled["lux"], again["lux"]), rtol=0, atol=1e-9)
    np.testing.assert_allclose(diff["stderr"], np.hypot(doubled["stderr"], again["stderr"]), rtol=1e-12)
    # two equal lights: twice the light, every cell brighter far beyond the noise
    assert np.all(np.array(diff["difference"]) > 3 * np.array(diff["stderr"]))
    assert diff["summary"]["increased"] == 16 and diff["summary"]["decreased"] == 0
    assert diff["summary"]["mean_after_lux"] == pytest.approx(2 * diff["summary"]["mean_before_lux"], rel=0.15)
    assert diff["warnings"] == []
    rows = list(csv.DictReader(io.StringIO(client.get(f"{base}/difference", params={
        "from": f"{rev}.0", "to": f"{rev}.1", "format": "csv"}).text)))
    assert len(rows) == 16 and list(rows[0])[-4:] == ["lux_from", "lux_to", "difference_lux", "stderr_lux"]
    assert float(rows[5]["difference_lux"]) == pytest.approx(np.ravel(diff["difference"])[5], rel=1e-8)
    r = client.get(f"{base}/difference.png", params={"from": f"{rev}.0", "to": f"{rev}.1"})
    assert r.status_code == 200 and r.content.startswith(PNG)

    # a push makes a new revision; the results of the old one stay; KEEP results at most, the oldest go first
    assert client.delete(f"/scenes/{sid}/lights/{second}").status_code == 204
    push_floor(client, sid, rev, dx=0.5)
    moved = simulate(client, sid, grid)
    assert moved["revision"] == rev + 1
    assert [e["key"] for e in listed(client, sid, grid)] == [f"{rev + 1}.0", f"{rev}.1", f"{rev}.0"]
    r = client.get(f"{base}/difference", params={"from": f"{rev}.1", "to": str(rev + 1)})
    assert r.status_code == 200 and r.json()["summary"]["decreased"] == 16
    assert client.post(f"/scenes/{sid}/lights", json={"type": "point", "position": [0.0, 0.0, H],
                                                      "intensity_cd": 3 * I_CD}).status_code == 201
    simulate(client, sid, grid)
    assert [e["key"] for e in listed(client, sid, grid)] == [f"{rev + 1}.1", f"{rev + 1}.0", f"{rev}.1"]

    # disk sensors are kept too (no map)
    simulate(client, sid, disk)
    (kept_disk,) = listed(client, sid, disk)
    assert kept_disk["type"] == "disk" and kept_disk["center"] == [0.0, 0.0, 0.0]
    text = client.get(f"/scenes/{sid}/sensors/{disk}/results/{kept_disk['key']}", params={"format": "csv"}).text
    assert text.splitlines()[1].startswith("0,0,0,0,0,")
    assert client.get(f"/scenes/{sid}/sensors/{disk}/results/{kept_disk['key']}/map.png").status_code == 404

    # the results outlive the process: a new app on the same data directory lists them
    with make_client(data, max_points=50, keep_results=KEEP) as fresh:
        assert [e["key"] for e in fresh.get(f"{base}/results").json()["results"]] == \
            [f"{rev + 1}.1", f"{rev + 1}.0", f"{rev}.1"]


@pytest.mark.parametrize(("path", "params", "status", "says"), [
    ("results/abc", {}, 422, "key"),
    ("results/1.2.3", {}, 422, "key"),
    ("results/99", {}, 404, "no kept result '99'"),
    ("results/1", {"format": "xml"}, 422, "format"),
    ("difference", {"from": "1"}, 422, "to"),
    ("difference", {"from": "99", "to": "1"}, 404, "no kept result '99'"),
    ("difference.png", {"from": "x", "to": "1"}, 422, "from"),
])
def test_bad_requests_say_what_is_wrong_and_change_nothing(world, path, params, status, says) -> None:
    client, sid, grid, _, _ = world
    before = client.get(f"/scenes/{sid}/sensors/{grid}/results").json()
    r = client.get(f"/scenes/{sid}/sensors/{grid}/{path}", params=params)
    assert r.status_code == status, r.text
    assert says in r.json()["detail"]
    assert client.get(f"/scenes/{sid}/sensors/{grid}/results").json() == before


def test_unknown_scene_or_sensor_is_404(world) -> None:
    client, sid, _, _, _ = world
    assert client.get(f"/scenes/{sid}/sensors/{UNKNOWN_ID}/results").status_code == 404
    assert client.get(f"/scenes/{UNKNOWN_ID}/sensors/{UNKNOWN_ID}/results").status_code == 404


def test_cells_of_different_grids_are_not_compared() -> None:
    a = {"key": "1.0", "type": "grid", "nu": 2, "nv": 2, "origin": [0, 0, 0], "u": [1, 0, 0], "v": [0, 1, 0],
         "lux": [[1, 2], [3, 4]], "stderr": [[0, 0], [0, 0]]}
    b = {**a, "key": "2.0", "nu": 4, "lux": [[1] * 4] * 2, "stderr": [[0] * 4] * 2}
    with pytest.raises(Invalid, match="a 2 x 2 grid at 1.0 and a 4 x 2 grid at 2.0"):
        difference(a, b)
    moved = difference(a, {**a, "key": "2.0", "origin": [1, 0, 0]})
    assert moved["warnings"] and "moved" in moved["warnings"][0]
