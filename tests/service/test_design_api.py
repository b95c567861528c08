"""The design loop through the REST API (issue 53): ``POST /elements/{id}/design`` tunes the dots' height on an
edge-lit guide as a job, keeps the chosen element with its record, and the scene switched to it lets out more light
on a fresh seed; a design that cannot run is a 422 before any job, changing nothing."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from service_helpers import make_client, uid

from tests.service.test_elements_api import ABOVE, _guide
from tests.service.test_pack_api import _follow

FLAT = {"type": "microstructure", "feature": {"shape": "dome", "radius_mm": 0.3, "height_mm": 0.02},
        "layout": {"type": "grid", "pitch_mm": [1.0, 1.0]}}
HEIGHT = [{"name": "feature.height_mm", "values": [0.02, 0.1, 0.25]}]


@pytest.fixture(scope="module")
def setup(tmp_path_factory: Any) -> Any:
    """(client, scene id, assignment id, sensor id, element id): the guide of test_elements_api, flat domes on it."""
    with make_client(Path(tmp_path_factory.mktemp("design"))) as client:
        sid = _guide(client)
        eid = client.post("/elements", json=FLAT).json()["id"]
        aid = client.post(f"/scenes/{sid}/elements", json={"element": eid, "node": uid(1), "facing": [0, 0, -1]}
                          ).json()["id"]
        sensor = client.post(f"/scenes/{sid}/sensors", json=ABOVE).json()["id"]
        yield client, sid, aid, sensor, eid


def test_the_design_job_finds_taller_domes_and_the_switched_scene_lets_out_more_light(setup: Any) -> None:
    client, sid, aid, sensor, eid = setup
    r = client.post(f"/elements/{eid}/design", json={"scene": sid, "assignment": aid, "sensor": sensor,
                                                      "parameters": HEIGHT, "objective": "mean", "photons": 30_000,
                                                      "seed": 2})
    assert r.status_code == 202, r.text
    polled: list[dict] = []
    job = _follow(client, r.headers["location"], seen=polled)
    assert job["status"] == "succeeded" and job["kind"] == "design" and job["element"] == eid, job
    res = job["result"]
    c = res["confirmation"]
    assert c["improved"] and c["improvement"] > 2 * c["improvement_stderr"], c
    assert res["values"]["feature.height_mm"] in (0.1, 0.25) and len(res["candidates"]) == 3
    assert any(p.get("stage") == "sweep" for p in polled)
    record = client.get(res["design_url"]).json()
    assert record["designed_from"] == eid and record["candidates"] == res["candidates"]
    png = client.get(res["png_url"])
    assert png.status_code == 200 and png.content[:4] == b"\x89PNG"
    _check_picture(record)
    new = res["element"]
    assert client.get(f"/elements/{new}").json()["body"]["feature"]["height_mm"] == res["values"]["feature.height_mm"]
    # the scene everybody queries is untouched until it is switched; then it reads more light on a fresh seed
    before = client.post(f"/scenes/{sid}/sensors/{sensor}/simulate", json={"max_photons": 30_000, "seed": 99,
                                                                          "estimator": "forward"}).json()
    assert client.put(f"/scenes/{sid}/elements/{aid}", json={"element": new}).status_code == 200
    after = client.post(f"/scenes/{sid}/sensors/{sensor}/simulate", json={"max_photons": 30_000, "seed": 99,
                                                                         "estimator": "forward"}).json()
    gain = np.mean(after["lux"]) - np.mean(before["lux"])
    err = np.hypot(np.sqrt(np.sum(np.square(before["stderr"]))), np.sqrt(np.sum(np.square(after["stderr"])))) / 6
    assert gain > 2 * err, (gain, err)
    assert client.put(f"/scenes/{sid}/elements/{aid}", json={"element": eid}).status_code == 200
    assert client.get(f"/elements/{eid}/design").status_code == 404   # the start was not made by a design loop


@pytest.mark.parametrize("change, words", [
    ({"parameters": [{"name": "feature.apex_deg", "values": [80, 90]}]}, "has no feature.apex_deg"),
    ({"parameters": [{"name": "feature.height_mm"}]}, "takes 'values', or 'lo', 'hi' and 'steps'"),
    ({"parameters": [{"name": "feature.height_mm", "lo": 0.01, "hi": 0.2, "steps": 9},
                     {"name": "feature.radius_mm", "lo": 0.3, "hi": 0.5, "steps": 9}]}, "81 combinations"),
    ({"parameters": []}, "parameters"),
    ({"objective": "brightest"}, "objective"),
    ({"objective": "half_angle", "goal": "lowest"}, "goal"),
    ({"pack_map": True}, "only a 'density' layout"),
    ({"assignment": "nope"}, "assignment"),
])
def test_a_design_that_cannot_run_is_a_422_before_any_job(setup: Any, change: dict, words: str) -> None:
    client, sid, aid, sensor, eid = setup
    library = client.get("/elements").json()
    assigned = client.get(f"/scenes/{sid}/elements").json()
    body = {"scene": sid, "assignment": aid, "sensor": sensor, "parameters": HEIGHT, **change}
    r = client.post(f"/elements/{eid}/design", json=body)
    assert r.status_code == 422 and words in r.text, r.text
    assert client.get("/elements").json() == library and client.get(f"/scenes/{sid}/elements").json() == assigned


def test_the_client_runs_a_design_and_reads_its_record(setup: Any) -> None:
    from lumenlink.client import Client

    client, sid, aid, sensor, eid = setup
    ll = Client("http://testserver", transport=client._transport)
    seen: list[dict] = []
    job = ll.design(eid, sid, aid, sensor, [{"name": "feature.height_mm", "lo": 0.05, "hi": 0.15, "steps": 2}],
                    objective="mean", photons=10_000, seed=5, progress=seen.append, poll=0.1)
    assert job["status"] == "succeeded", job
    values = [c["values"]["feature.height_mm"] for c in ll.design_record(job["result"]["element"])["candidates"]]
    assert values == [0.05, 0.15] and seen


def _check_picture(record: dict) -> None:
    """design.png's figure says what the record says: a point and error bar per candidate read, at its values, the
    start's line, the chosen one starred, the fresh-seed confirmation in the title."""
    from service.design import plot_figure

    ax = plot_figure(record).axes[0]
    read = [c for c in record["candidates"] if c["objective"] is not None]
    (points, *_), = [c.lines for c in ax.containers]
    assert list(points.get_ydata()) == [c["objective"] for c in read]
    assert [t.get_text() for t in ax.get_xticklabels()] == [f"{c['values']['feature.height_mm']:g}" for c in read]
    assert any(line.get_marker() == "*" and list(line.get_ydata()) == [
        next(c["objective"] for c in read if c["values"] == record["values"])] for line in ax.lines)
    c = record["confirmation"]
    assert f"gain {c['improvement']:.3g}" in ax.get_title()
    assert any(t.get_text().startswith(f"start {record['baseline']['objective']:.4g}")
               for t in ax.get_legend().get_texts())


def test_a_spread_design_s_picture_names_the_angle_and_its_goal() -> None:
    """A ``half_angle`` record drawn: its axis says the half-luminance angle in degrees, lower is better."""
    from service.design import plot_figure

    read = [{"values": {"feature.apex_deg": a}, "objective": o, "stderr": 0.5} for a, o in ((80, 41.0), (90, 35.5))]
    record = {"candidates": read, "values": {"feature.apex_deg": 90}, "objective": "half_angle", "goal": "min",
              "quantity": "luminance", "unit": "deg", "stopped": "done", "confirmation": None,
              "baseline": {"objective": 41.0, "stderr": 0.5}}
    ax = plot_figure(record).axes[0]
    assert ax.get_ylabel() == "half-luminance viewing angle (°) · lower is better"
    assert [t.get_text() for t in ax.get_xticklabels()] == ["80", "90"]
