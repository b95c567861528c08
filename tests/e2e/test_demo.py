"""`make demo` end to end with small photon counts: the facts it prints are the facts that happened.

Runs the real path — cadquery model, STEP with UUIDs, adapter push over HTTP to the service on a
loopback port, materials/lights/sensor, photon tracing, maps, a door move and a lens edit — and
checks what the issue asks the demo to show: the door move builds no bottom level, the lens edit
builds exactly one, every assignment survives both pushes, and the three PNGs are real images.
"""

from __future__ import annotations

import io
import os
import tempfile
from pathlib import Path
from typing import Any

import httpx
import matplotlib.image as mpimg
import numpy as np
import pytest
from rich.console import Console

from lumenlink.demo import GRID_NU, GRID_NV, Narrator, run_demo


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo")
    buffer = io.StringIO()
    narrator = Narrator(Console(file=buffer, width=200, highlight=False, soft_wrap=True))
    report = run_demo(out, photons=20_000, narrator=narrator, serve=lambda url: SERVED.update(_look_at(url)))
    return report, buffer.getvalue()


SERVED: dict[str, Any] = {}
CHROMIUM = Path("/usr/bin/chromium")


def _look_at(view_url: str) -> dict[str, Any]:
    """What `lumenlink demo --serve` serves while it waits: the page, its state and, where Chromium is installed,
    what a browser draws of it (tests/e2e/test_pages.py tests the page itself)."""
    seen: dict[str, Any] = {"url": view_url, "page": httpx.get(view_url).status_code,
                            "state": httpx.get(view_url + "/state").json()}
    if CHROMIUM.exists():
        from playwright.sync_api import sync_playwright

        artifacts = Path(os.environ.get("LUMENLINK_ARTIFACTS") or Path(tempfile.gettempdir()) / "lumenlink-artifacts")
        artifacts.mkdir(parents=True, exist_ok=True)
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=str(CHROMIUM), args=[
                "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                "--disable-background-networking", "--disable-component-update", "--disable-sync"])
            page = browser.new_page(viewport={"width": 1100, "height": 700})
            errors: list[str] = []
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.goto(view_url)
            page.wait_for_function("window.lumenlink && window.lumenlink.ready", timeout=60_000)
            seen["browser"] = {"counts": page.evaluate("window.lumenlink.counts()"), "errors": errors}
            page.screenshot(path=str(artifacts / "demo-view.png"))
            browser.close()
    return seen


def test_first_push_uploads_each_distinct_geometry_once(demo) -> None:
    report, log = demo
    first = report.pushes["initial"]
    assert first.revision == 1
    nodes_with_mesh = sum(1 for r in first.raw["added"])  # every node is new on the first push
    # four wheels share one mesh: fewer uploads than nodes, and each built once
    assert first.uploaded == first.blas_built < nodes_with_mesh
    assert f"{first.uploaded} of {first.uploaded} distinct geometries uploaded" in log


def test_door_move_is_a_transform_change_and_builds_no_bottom_level(demo) -> None:
    report, log = demo
    doors = report.pushes["doors"]
    assert doors.revision == 2
    assert len(doors.moved) == 2 and doors.geometry_changed == []
    assert doors.blas_built == 0 and doors.uploaded == 0
    assert "bottom levels built: 0" in log and "door_left" in log and "door_right" in log


def test_lens_edit_builds_exactly_one_bottom_level(demo) -> None:
    report, log = demo
    lens = report.pushes["lens"]
    assert lens.revision == 3
    assert len(lens.geometry_changed) == 1 and lens.moved == []
    assert lens.blas_built == 1 and lens.uploaded == 1
    assert "geometry changed lens" in log and "bottom levels built: 1" in log
    assert lens.tlas_ms >= 0.0


def test_every_assignment_survives_both_pushes(demo) -> None:
    report, log = demo
    before, after = report.assignments_before, report.assignments_after
    kinds = {key.split(":")[0] for key in before}
    assert kinds == {"material", "light", "sensor", "object"}
    # car, windscreen, lens, housing, 4 wheels, and the floor object's own material
    assert sum(k.startswith("material") for k in before) == 9
    assert sum(k.startswith("light") for k in before) == 2
    assert after == before  # same ids, same bodies, none orphaned
    assert all(orphaned is False for _, orphaned in after.values())
    assert "all kept, none orphaned" in log


def test_queries_answer_at_the_revision_they_describe(demo) -> None:
    report, _ = demo
    b, a = report.grid_before, report.grid_after
    assert (b["revision"], a["revision"]) == (1, 3)
    for grid in (b, a):
        lux = np.asarray(grid["lux"])
        assert lux.shape == (GRID_NV, GRID_NU) and np.all(lux >= 0) and lux.max() > 0
        assert grid["photons"] > 0 and "fresnel" in grid["effects"]  # glass lens and windscreen
    assert report.points_before["revision"] == 1 and report.points_after["revision"] == 3
    assert report.change.cells == GRID_NU * GRID_NV


def test_maps_are_non_empty_pngs(demo) -> None:
    report, log = demo
    assert set(report.maps) == {"before", "after", "difference"}
    for path in report.maps.values():
        data = path.read_bytes()
        assert data.startswith(b"\x89PNG\r\n\x1a\n") and len(data) > 10_000
        image = mpimg.imread(io.BytesIO(data), format="png")
        assert image.shape[0] > 300 and image.shape[1] > 500
        assert str(path) in log
    assert report.view_url.split("/scenes/")[0] + "/docs" in log   # the demo served (--serve): its live docs


def test_log_says_how_long_it_took(demo) -> None:
    report, log = demo
    assert report.seconds > 0 and 0 <= report.compile_seconds <= report.seconds
    for step in ("1. ", "2. ", "3a. ", "3b. ", "4a. ", "4b. ", "5. ", "6. "):
        assert f"] {step}" in log


def test_a_missing_part_stops_the_demo_with_its_name_and_no_output(tmp_path, monkeypatch, capsys) -> None:
    import sys

    from lumenlink import demo as demo_module

    monkeypatch.setitem(sys.modules, "cad_adapter.samples", None)  # importing it now raises ImportError
    code = demo_module.run(tmp_path / "out", photons=10_000)
    out = capsys.readouterr().out
    assert code == 2
    assert "cad_adapter.samples is not built yet (issue 4)" in out and "no result above was made up" in out
    assert not list((tmp_path / "out").glob("*.png"))


def test_photon_budget_is_checked(tmp_path) -> None:
    with pytest.raises(ValueError, match="at least 1000"):
        run_demo(tmp_path, photons=10)


def test_serve_keeps_the_service_up_with_the_model_page(demo) -> None:
    report, log = demo
    assert SERVED["url"] == report.view_url and report.view_url.endswith("/view")
    assert f"open {report.view_url} in a browser" in log
    assert SERVED["page"] == 200
    state = SERVED["state"]
    names = {n["name"] for n in state["nodes"]}
    assert {"car", "lens", "door_left", "wheel_fl"} <= names
    assert any(r["object"] for r in state["instances"])   # the floor, owned by the simulation
    [grid] = [s for s in state["sensors"] if s["type"] == "grid"]
    [surface] = [s for s in state["sensors"] if s["type"] == "surface"]   # the car's own surfaces, per triangle
    parts = surface["result"]["instances"]
    assert surface["result"]["revision"] == 3 and len(parts) >= 8   # body, doors, wheels, lamp...
    assert max(max(p["lux"]) for p in parts) > 0 and all(len(p["lux"]) == len(p["stderr"]) for p in parts)
    lux = np.asarray(grid["result"]["lux"])   # the floor grid in false colour: its result at the last revision
    assert grid["result"]["revision"] == 3 and lux.shape == (GRID_NV, GRID_NU) and lux.max() > 0
    assert state["last_push"]["revision"] == 3 and len(state["last_push"]["geometry_changed"]) == 1
    if "browser" in SERVED:
        assert SERVED["browser"]["counts"] == {"instances": len(state["instances"]), "sensors": 1}
        assert SERVED["browser"]["errors"] == []
