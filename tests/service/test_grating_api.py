"""Grating elements through the REST API (issue 52): solved by RCWA when posted, content-addressed, kept like every
element and read back after a restart; bad or too costly bodies are precise 422s that store nothing; a grating
goes onto a scene's face and diffracts there (tests/tracer/elements/test_grating_transport.py has the physics)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from service_helpers import glb, make_client, node, uid

from tests.tracer.transport_scenes import box
from tracer.elements import grating

GRATING = {"type": "grating", "profile": {"shape": "lamellar", "fill": 0.5}, "period_um": 1.0, "depth_um": 0.3,
           "ridge": None, "substrate_ior": 1.5, "wavelengths_nm": [500, 600], "wavelength_count": 2,
           "angles": {"polar_deg": [0, 30], "azimuth_deg": [0]}, "orders": 5}


@pytest.fixture
def client(tmp_path: Path) -> Any:
    with make_client(tmp_path) as c:
        yield c


def _stored(tmp_path: Path) -> list[str]:
    d = tmp_path / "elements"
    return sorted(p.name for p in d.iterdir()) if d.exists() else []


def test_a_grating_is_solved_once_kept_and_answered_by_the_id_of_its_body(client: Any, tmp_path: Path) -> None:
    first = client.post("/elements", json=GRATING)
    assert first.status_code == 201, first.text
    s = first.json()
    assert s["type"] == "grating" and s["solver"] == grating.SOLVER and s["features"] is None
    assert s["id"] == grating.element_id(grating.check(GRATING))
    assert s["bytes"] > 0 and s["prepare_seconds"] > 0.0
    again = client.post("/elements", json={**GRATING, "grooves_along": "v", "ambient_ior": 1.0})   # defaults spelt
    assert again.status_code == 200 and again.json() == s
    assert client.post("/elements", json={**GRATING, "depth_um": 0.31}).json()["id"] != s["id"]
    listed = {e["id"]: e for e in client.get("/elements").json()}
    assert listed[s["id"]] == s
    detail = client.get(f"/elements/{s['id']}").json()
    assert detail["body"] == grating.check(GRATING) and detail["solver"] == grating.SOLVER
    # the file is the table's deterministic bytes: the same body solved again writes the same file
    kept = (tmp_path / "elements" / f"{s['id']}.npz").read_bytes()
    assert kept == grating.prepare(GRATING).to_bytes()


def test_a_kept_grating_is_read_back_after_a_restart_without_solving(tmp_path: Path) -> None:
    with make_client(tmp_path) as c:
        s = c.post("/elements", json=GRATING).json()
    with make_client(tmp_path) as c:
        assert c.get(f"/elements/{s['id']}").json()["prepare_seconds"] == s["prepare_seconds"]
        table = c.app.state.manager.scenes.elements.get(s["id"])
        assert isinstance(table, grating.GratingTable) and table.id == s["id"]
        assert np.isfinite(table.efficiency).any()


@pytest.mark.parametrize(("change", "says"), [
    ({"profile": {"shape": "lamellar", "fill": 0}}, "profile.fill must be in (0, 1]"),
    ({"period_um": [1, 2]}, "period_um of a 1-D profile (lamellar) is one number in um"),
    ({"ridge": {"ior": [1.5, -1]}}, "ridge.ior[1] must be in [0, 50]"),
    ({"wavelengths_nm": [380]}, "wavelengths_nm must be [lo, hi] in nm"),
    ({"wavelengths_nm": [380, 780], "wavelength_count": 401, "orders": 8,
      "angles": {"polar_deg": list(range(0, 89)), "azimuth_deg": [0, 90, 180]}}, "one request prepares at most 300 s"),
    ({"period_um": 2.0}, "orders 5 keeps -5..5, but orders up to |m| = "),
])
def test_bad_and_too_costly_gratings_are_precise_422s_that_store_nothing(client: Any, tmp_path: Path,
                                                                          change: dict, says: str) -> None:
    r = client.post("/elements", json={**GRATING, **change})
    assert r.status_code == 422, r.text
    assert says in r.text
    assert client.get("/elements").json() == [] and _stored(tmp_path) == []


def _scene(client: Any) -> str:
    sid = client.post("/scenes", json={"name": "plate"}).json()["id"]
    v, t = box([0, 0, 0], [20, 20, 2])
    gid, data = glb(v.astype(np.float32), t)
    assert client.put(f"/geometries/{gid}", content=data, headers={"content-type": "model/gltf-binary"}
                      ).status_code in (200, 201)
    nodes = [node(uid(0), None, "optics"), node(uid(1), uid(0), "plate", geometry=gid)]
    r = client.put(f"/scenes/{sid}/document", json={"base_revision": 0, "length_unit": "mm", "nodes": nodes})
    assert r.status_code == 200, r.text
    return sid


def test_a_grating_on_a_face_diffracts_makes_the_scene_spectral_and_says_where_its_table_ran_out(client: Any) -> None:
    """Library -> assignment -> query: the grating goes onto the plate's top face, the answer's effects hold
    `diffraction` and `spectral` and say why, and light that meets it outside its table (here: inside the plate, at
    polar angles past the table's 30 degrees and on the azimuth 180 it was not solved for) is counted in the
    answer's warnings. A 'bsdf' model for a grating is a 422 naming the field, and packing one is refused."""
    eid = client.post("/elements", json=GRATING).json()["id"]
    sid = _scene(client)
    assert client.put(f"/scenes/{sid}/materials/{uid(1)}", json={"type": "dielectric", "ior": 1.5}
                      ).status_code in (200, 201)
    r = client.post(f"/scenes/{sid}/elements", json={"element": eid, "node": "optics/plate", "facing": [0, 0, 1],
                                                     "model": "bsdf"})
    assert r.status_code == 422 and "model: element" in r.text and "is a grating" in r.text, r.text
    assert client.get(f"/scenes/{sid}/elements").json() == []
    r = client.post(f"/scenes/{sid}/elements", json={"element": eid, "node": "optics/plate", "facing": [0, 0, 1]})
    assert r.status_code == 201, r.text
    assert r.json()["applied"] and r.json()["support"]["triangles"] == 2
    client.post(f"/scenes/{sid}/lights", json={"type": "collimated", "origin": [0.01, 0.01, 0.005],
                                               "direction": [0, 0, -1], "radius": 0.003, "illuminance_lx": 1000,
                                               "spectrum": {"type": "monochromatic", "nm": 550}})
    a = client.post(f"/scenes/{sid}/illuminance", json={"points": [[0.01, 0.01, -0.001]], "normals": [[0, 0, 1]],
                                                       "max_photons": 3000, "seed": 1, "estimator": "forward"})
    assert a.status_code == 200, a.text
    body = a.json()
    assert {"diffraction", "spectral"} <= set(body["effects"])
    assert body["effect_reasons"]["diffraction"] == "on: called for by a grating element"
    assert body["lux"][0] > 0
    assert any("met a grating where its table of orders ran out" in w for w in body["warnings"]), body
    r = client.post(f"/elements/{eid}/pack", json={"scene": sid, "assignment": "x", "sensor": "y"})
    assert r.status_code == 422 and "is a grating" in r.text


def test_the_openapi_document_builds_and_describes_the_solver(client: Any) -> None:
    doc = client.get("/openapi.json").json()
    summary = doc["components"]["schemas"]["ElementSummary"]["properties"]
    assert "solver" in summary
    examples = doc["paths"]["/elements"]["post"]["requestBody"]["content"]["application/json"]["examples"]
    assert examples["grating"]["value"]["type"] == "grating"
    r = client.post("/elements", json=examples["wire grid"]["value"])
    assert r.status_code == 201, r.text


def test_orders_png_plots_a_gratings_efficiencies_and_refuses_what_it_cannot_plot(client: Any) -> None:
    """``GET /elements/{id}/orders.png``: a PNG at the table's first incidence, at another it holds, lit from either
    side; a 422 naming the field for an angle the table was not solved at or an unknown side, a 422 for an element
    that is not a grating, a 404 for an id the library lacks."""
    eid = client.post("/elements", json=GRATING).json()["id"]
    for query in ("", "?polar_deg=30", "?polar_deg=0&azimuth_deg=0&lit_from=substrate"):
        r = client.get(f"/elements/{eid}/orders.png{query}")
        assert r.status_code == 200 and r.headers["content-type"] == "image/png", r.text
        assert r.content[:8] == b"\x89PNG\r\n\x1a\n"
    r = client.get(f"/elements/{eid}/orders.png?polar_deg=45")
    assert r.status_code == 422 and "polar_deg 45 is not one of the table's angles: give one of [0.0, 30.0]" in r.text
    r = client.get(f"/elements/{eid}/orders.png?lit_from=above")
    assert r.status_code == 422 and "lit_from" in r.text
    dots = client.post("/elements", json={"type": "microstructure", "feature": {"shape": "dome", "radius_mm": 0.05,
                                                                                 "height_mm": 0.02},
                                          "layout": {"type": "grid", "pitch_mm": [0.2, 0.2]}}).json()["id"]
    r = client.get(f"/elements/{dots}/orders.png")
    assert r.status_code == 422 and "is not a grating" in r.text
    assert client.get(f"/elements/{'0' * 64}/orders.png").status_code == 404


def test_a_grating_prepares_as_a_job_with_progress_on_request(client: Any) -> None:
    """``POST /elements?mode=async``: a grating's body is checked at once (a 422, no job, for a bad one), then solved
    as a job whose progress counts the table points (both sides) and whose result is the element's summary; the same
    body again answers 200 with that summary, no job."""
    r = client.post("/elements?mode=async", json={**GRATING, "period_um": [1, 2]})
    assert r.status_code == 422 and "period_um" in r.text
    r = client.post("/elements?mode=async", json=GRATING)
    assert r.status_code == 202, r.text
    deadline = time.monotonic() + 120.0
    while (state := client.get(r.json()["url"]).json())["status"] not in ("succeeded", "failed", "cancelled"):
        assert time.monotonic() < deadline, state
        time.sleep(0.05)
    assert state["status"] == "succeeded", state
    progress = state["progress"]
    assert progress["fraction"] == 1.0 and progress["points"] == progress["points_total"] == 2 * 2 * 2 * 1
    eid = state["result"]["id"]
    assert client.get(f"/elements/{eid}").json()["type"] == "grating"
    again = client.post("/elements?mode=async", json=GRATING)
    assert again.status_code == 200 and again.json()["id"] == eid
    assert client.post("/elements", json=GRATING).json()["id"] == eid
