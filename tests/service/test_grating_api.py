"""Grating elements through the REST API (issue 52): solved by RCWA when posted, content-addressed, kept like every
element and read back after a restart; bad or too costly bodies are precise 422s that store nothing; a grating
cannot go onto a scene's face yet (its inner model in the tracer is not built), a 422 that stores nothing."""

from __future__ import annotations

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
    ({"wavelengths_nm": [380, 780], "wavelength_count": 401, "orders": 6,
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


def test_assigning_a_grating_to_a_face_is_a_422_saying_its_inner_model_is_not_built_yet(client: Any) -> None:
    eid = client.post("/elements", json=GRATING).json()["id"]
    sid = _scene(client)
    r = client.post(f"/scenes/{sid}/elements", json={"element": eid, "node": "optics/plate", "facing": [0, 0, 1]})
    assert r.status_code == 422, r.text
    assert "is a grating" in r.text and "not built yet (issue 52)" in r.text
    assert client.get(f"/scenes/{sid}/elements").json() == []
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
