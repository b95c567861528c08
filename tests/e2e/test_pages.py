"""The pages for people in a real browser (issue 23): Debian's Chromium, headless, driven by Playwright, against a
real `lumenlink serve` process.

- ``/docs`` and ``/redoc`` render with every request going to the service itself (no CDN) and no console error;
- ``/`` lists the scene and links to its view;
- ``/scenes/{id}/view``: the model appears (one three.js mesh per instance), the grid sensor plane is drawn in the
  false colour of its result once a simulation lands, a push moves the part without a reload (server-sent events)
  and highlights it, a job shows up with its final state, a click on a sensor cell reports the floor's node path,
  its material and the cell's lux ± error, the linear/log switch recolours the plane.
- a surface sensor on the box colours its triangles; a click on one reports that triangle's lux ± error.
- "render this view" shows the view's luminance image: a coarse one first, then the full one, refined.

Screenshots go to ``$LUMENLINK_ARTIFACTS/pages`` (default ``<tmp>/lumenlink-artifacts/pages``), never into the repo.
Skipped, saying why, only where Chromium or Playwright is not installed (`make test` installs both: the Makefile's
``chromium`` target, pyproject's dev extra). Tiny scene, small photon budgets: well under a minute once the
kernels are compiled.
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests"))

from service_process import running_service  # noqa: E402

CHROMIUM = Path("/usr/bin/chromium")
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]
ARTIFACTS = Path(os.environ.get("LUMENLINK_ARTIFACTS") or Path(tempfile.gettempdir()) / "lumenlink-artifacts") / "pages"

if not CHROMIUM.exists():
    pytest.skip(f"{CHROMIUM} is missing (Debian's chromium package: `make chromium` installs it as root)",
                allow_module_level=True)
sync_api = pytest.importorskip("playwright.sync_api", reason="playwright (pyproject's dev extra) is not installed")

ROOM, FLOOR, BOX = (f"00000000-0000-4000-8000-00000000000{k}" for k in (1, 2, 3))
GRID = {"type": "grid", "name": "floor grid", "origin": [-1.0, -1.0, 0.0], "u": [2.0, 0.0, 0.0],
        "v": [0.0, 2.0, 0.0], "nu": 4, "nv": 4}
WAIT_MS = 120_000   # a first simulation may compile kernels (numba caches them on disk for the next run)


def _mesh(vertices: list[list[float]], triangles: list[list[int]]) -> tuple[str, bytes]:
    from cad_adapter.glb import encode_glb
    from tracer.geometry_id import geometry_id

    v, f = np.asarray(vertices, np.float32), np.asarray(triangles, np.uint32)
    return geometry_id(v, f), encode_glb(v, f)


def _translation(x: float, y: float, z: float) -> list[float]:
    return [1, 0, 0, x, 0, 1, 0, y, 0, 0, 1, z, 0, 0, 0, 1]


def _document(base: int, box_x: float, floor: str, box: str) -> dict[str, Any]:
    return {"base_revision": base, "length_unit": "m", "nodes": [
        {"uuid": ROOM, "parent": None, "name": "room", "transform": _translation(0, 0, 0), "geometry": None},
        {"uuid": FLOOR, "parent": ROOM, "name": "floor", "transform": _translation(-2, -2, 0), "geometry": floor},
        {"uuid": BOX, "parent": ROOM, "name": "box", "transform": _translation(box_x, 0.8, 0), "geometry": box,
         "color": [0.8, 0.2, 0.2]}]}


@pytest.fixture(scope="module")
def service(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Any]]:
    """A real service with one tiny scene: a 4 m floor, a 0.4 m box on it, a point light, a 4×4 floor grid."""
    with running_service(tmp_path_factory.mktemp("pages")) as base, httpx.Client(base_url=base, timeout=300) as http:
        scene = http.post("/scenes", json={"name": "pages test room"}).json()["id"]
        floor = _mesh([[0, 0, 0], [4, 0, 0], [4, 4, 0], [0, 4, 0]], [[0, 1, 2], [0, 2, 3]])
        s = 0.4
        corners = [[x, y, z] for z in (0, s) for y in (0, s) for x in (0, s)]
        box = _mesh(corners, [[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
                              [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]])
        for gid, data in (floor, box):
            r = http.put(f"/geometries/{gid}", content=data, headers={"content-type": "model/gltf-binary"})
            assert r.status_code in (200, 201), r.text
        r = http.put(f"/scenes/{scene}/document", json=_document(0, 0.6, floor[0], box[0]))
        assert r.status_code == 200, r.text
        assert http.put(f"/scenes/{scene}/materials/{FLOOR}", json={"type": "lambertian", "reflectance": 0.5}
                        ).status_code == 200
        assert http.post(f"/scenes/{scene}/lights", json={"type": "point", "name": "bulb", "position": [0, 0, 2],
                                                          "intensity_cd": 200.0}).status_code == 201
        sensor = http.post(f"/scenes/{scene}/sensors", json=GRID)
        assert sensor.status_code == 201, sensor.text
        yield {"base": base, "http": http, "scene": scene, "sensor": sensor.json()["id"], "floor": floor[0],
               "box": box[0]}


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    with sync_api.sync_playwright() as p:
        b = p.chromium.launch(executable_path=str(CHROMIUM), args=ARGS)
        try:
            yield b
        finally:
            b.close()


@pytest.fixture(scope="module", autouse=True)
def artifacts() -> Path:
    shutil.rmtree(ARTIFACTS, ignore_errors=True)
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    return ARTIFACTS


class Watched:
    """A page with its console errors, page errors and every URL it requested."""

    def __init__(self, browser: Any) -> None:
        self.context = browser.new_context(viewport={"width": 1100, "height": 700})
        self.page = self.context.new_page()
        self.errors: list[str] = []
        self.requests: list[str] = []
        self.page.on("console", lambda m: self.errors.append(f"console.{m.type}: {m.text}") if m.type == "error"
                     else None)
        self.page.on("pageerror", lambda e: self.errors.append(f"page error: {e}"))
        self.page.on("request", lambda r: self.requests.append(r.url))

    def close(self) -> None:
        self.context.close()


@pytest.fixture
def watched(browser: Any) -> Iterator[Watched]:
    w = Watched(browser)
    try:
        yield w
    finally:
        w.close()


@pytest.mark.parametrize("path, rendered", [("/docs", ".opblock"), ("/redoc", "[data-section-id^='operation']")])
def test_api_docs_render_from_the_service_alone(service: dict[str, Any], watched: Watched, artifacts: Path,
                                                path: str, rendered: str) -> None:
    page = watched.page
    page.goto(service["base"] + path)
    page.wait_for_selector(rendered, timeout=30_000)
    assert page.locator(rendered).count() >= 10   # the operations are listed, so the OpenAPI document was read
    page.screenshot(path=str(artifacts / f"{path.strip('/')}.png"))
    foreign = [u for u in watched.requests if not u.startswith(service["base"]) and not u.startswith("data:")
               and not u.startswith("blob:")]
    assert foreign == [], f"{path} fetched from elsewhere: {foreign}"
    assert watched.errors == []


def test_index_links_each_scene_to_its_view(service: dict[str, Any], watched: Watched) -> None:
    page = watched.page
    page.goto(service["base"] + "/")
    link = page.get_by_role("link", name="pages test room")
    assert link.get_attribute("href") == f"/scenes/{service['scene']}/view"
    link.click()
    page.wait_for_function("window.lumenlink && window.lumenlink.ready", timeout=30_000)
    assert watched.errors == []


def _wait(page: Any, expression: str, arg: Any = None, timeout: int = 30_000) -> Any:
    return page.wait_for_function(expression, arg=arg, timeout=timeout).json_value()


def test_the_view_draws_the_model_follows_results_and_pushes_and_reports_a_click(
        service: dict[str, Any], watched: Watched, artifacts: Path) -> None:
    page, http, scene, sensor = watched.page, service["http"], service["scene"], service["sensor"]
    page.goto(f"{service['base']}/scenes/{scene}/view")
    _wait(page, "window.lumenlink.ready && window.lumenlink.connection === 'live'")
    page.evaluate("window.__not_reloaded = true")

    # the model: one three.js mesh per instance (floor, box), the sensor plane, the light
    assert page.evaluate("window.lumenlink.counts()") == {"instances": 2, "sensors": 1}
    state = page.evaluate("window.lumenlink.state")
    assert state["scene"]["revision"] == 1 and [s["result"] for s in state["sensors"]] == [None]
    assert [light["name"] for light in state["lights"]] == ["bulb"]
    box = next(r for r in state["instances"] if r["node"] == BOX)
    assert page.evaluate("i => window.lumenlink.matrixOf(i)", box["instance"])[3] == pytest.approx(0.6)
    centre = [-0.75, 0.75, 0.0]   # the middle of cell (0, 3): u along x, v along y, 0.5 m cells
    at = page.evaluate("p => window.lumenlink.screenOf(p)", centre)
    grey = page.evaluate("([x, y]) => window.lumenlink.pixelAt(x, y)", [at["x"], at["y"]])
    page.screenshot(path=str(artifacts / "view-before.png"))

    # a simulation through the API: the page hears of its result and colours the plane, no reload
    result = http.post(f"/scenes/{scene}/sensors/{sensor}/simulate", json={"max_photons": 20_000, "seed": 3},
                       timeout=WAIT_MS / 1000)
    assert result.status_code == 200, result.text
    lux = result.json()["lux"]
    _wait(page, "window.lumenlink.state.sensors[0].result !== null", timeout=WAIT_MS)
    assert page.evaluate("window.lumenlink.state.sensors[0].result.lux") == lux
    assert any(e["name"] == "result" for e in page.evaluate("window.lumenlink.events"))
    expected = [round(255 * c) for c in page.evaluate(f"window.lumenlink.colourOf({lux[3][0]})")]
    drawn = page.evaluate("([x, y]) => window.lumenlink.pixelAt(x, y)", [at["x"], at["y"]])
    assert drawn[:3] == pytest.approx(expected, abs=10), (drawn, expected, grey)
    assert drawn[:3] != grey[:3]
    page.screenshot(path=str(artifacts / "view-simulated.png"))

    # a click on that cell: the floor's path and material, the cell's lux ± error
    page.mouse.click(at["x"], at["y"])
    pick = _wait(page, "window.lumenlink.lastPick")
    r = result.json()
    assert pick["sensor"]["i"] == 0 and pick["sensor"]["j"] == 3
    assert pick["lux"] == r["lux"][3][0] and pick["stderr"] == r["stderr"][3][0]
    assert pick["node"]["path"] == "room/floor" and pick["node"]["chain"] == "room › floor"
    assert pick["material"] == {"type": "lambertian", "reflectance": 0.5}
    assert f"{r['lux'][3][0]:.0f}" in page.locator("#pick").inner_text() or r["lux"][3][0] < 100

    # the log scale recolours the plane
    page.check("input[value=log]")
    log_expected = [round(255 * c) for c in page.evaluate(f"window.lumenlink.colourOf({lux[3][0]})")]
    drawn_log = page.evaluate("([x, y]) => window.lumenlink.pixelAt(x, y)", [at["x"], at["y"]])
    assert drawn_log[:3] == pytest.approx(log_expected, abs=10)
    page.check("input[value=linear]")

    # an async job: it shows up with its final state through the event stream
    job = http.post(f"/scenes/{scene}/sensors/{sensor}/simulate?mode=async", json={"max_photons": 20_000, "seed": 4})
    assert job.status_code == 202, job.text
    _wait(page, "id => window.lumenlink.jobs.some(j => j.id === id && j.status === 'succeeded')", job.json()["id"],
          timeout=WAIT_MS)

    # a push moves the box: the page follows without a reload, the box is drawn at its new place and highlighted
    r = http.put(f"/scenes/{scene}/document", json=_document(1, -1.5, service["floor"], service["box"]))
    assert r.status_code == 200 and r.json()["moved"] == [BOX], r.text
    _wait(page, "window.lumenlink.revision === 2 && window.lumenlink.state.last_push !== null")
    assert page.evaluate("window.__not_reloaded") is True
    assert page.evaluate("window.lumenlink.state.last_push.moved") == [BOX]
    assert page.evaluate("i => window.lumenlink.matrixOf(i)", box["instance"])[3] == pytest.approx(-1.5)
    assert "moved: 1" in page.locator("#changes").inner_text()
    # the push made the result stale: the plane is grey again until the next simulation
    assert page.evaluate("window.lumenlink.state.sensors[0].result") is None
    page.screenshot(path=str(artifacts / "view-after-push.png"))
    assert watched.errors == []


def test_a_surface_sensor_colours_the_model_and_a_click_reports_its_triangle(
        service: dict[str, Any], watched: Watched, artifacts: Path) -> None:
    """The box's own surfaces in false colour per triangle: the clicked triangle's lux ± error is the answer's."""
    page, http, scene = watched.page, service["http"], service["scene"]
    made = http.post(f"/scenes/{scene}/sensors", json={"type": "surface", "name": "box surfaces", "node": "room/box"})
    assert made.status_code == 201, made.text
    result = http.post(f"/scenes/{scene}/sensors/{made.json()['id']}/simulate",
                       json={"max_photons": 200_000, "seed": 5}, timeout=WAIT_MS / 1000)
    assert result.status_code == 200, result.text
    [part] = result.json()["instances"]
    assert part["node"] == BOX and part["path"] == "room/box" and len(part["lux"]) == 12
    page.goto(f"{service['base']}/scenes/{scene}/view")
    _wait(page, "window.lumenlink.ready && window.lumenlink.state.sensors.some(s => s.type === 'surface' && s.result)")
    box = next(r for r in page.evaluate("window.lumenlink.state.instances") if r["node"] == BOX)
    m = np.asarray(box["matrix"], float).reshape(4, 4)
    top = 2   # triangle [4, 5, 6] of the box: its top face (z = 0.4 m), front side up, lit by the bulb above
    centroid = m[:3, :3] @ np.array([0.4 / 3, 0.4 / 3, 0.4]) + m[:3, 3]
    at = page.evaluate("p => window.lumenlink.screenOf(p)", centroid.tolist())
    expected = [round(255 * c) for c in page.evaluate(f"window.lumenlink.colourOf({part['lux'][top]})")]
    drawn = page.evaluate("([x, y]) => window.lumenlink.pixelAt(x, y)", [at["x"], at["y"]])
    assert drawn[:3] == pytest.approx(expected, abs=10), (drawn, expected)
    page.screenshot(path=str(artifacts / "view-surface.png"))
    page.mouse.click(at["x"], at["y"])
    pick = _wait(page, "window.lumenlink.lastPick")
    assert pick["node"]["path"] == "room/box" and pick["triangle"] == top
    assert pick["lux"] == part["lux"][top] and pick["stderr"] == part["stderr"][top] and pick["lux"] > 0
    assert "triangle 2" in page.locator("#pick").inner_text()
    assert watched.errors == []


def test_render_this_view_shows_a_coarse_image_then_refines_it(service: dict[str, Any], watched: Watched,
                                                               artifacts: Path) -> None:
    """"render this view" makes camera sensors of the view shown: a coarse image (40 rows) appears beside the 3D
    view, then the full one (120 rows) replaces it, pass after pass, each image a PNG of the camera's size."""
    page = watched.page
    page.goto(f"{service['base']}/scenes/{service['scene']}/view")
    _wait(page, "window.lumenlink.ready && window.lumenlink.connection === 'live'")
    page.get_by_role("button", name="render this view").click()
    _wait(page, "window.lumenlink.render && window.lumenlink.render.passes.length >= 1", timeout=WAIT_MS)
    first = page.evaluate("window.lumenlink.render.passes[0]")
    assert first["coarse"] and first["height"] == 40
    _wait(page, "window.lumenlink.render.passes.length >= 2", timeout=WAIT_MS)
    _wait(page, "(() => { const i = document.getElementById('render'); return !i.hidden && i.complete && "
                "i.naturalHeight === 120; })()", timeout=30_000)
    second = page.evaluate("window.lumenlink.render.passes[1]")
    assert not second["coarse"] and second["height"] == 120 and second["photons"] > first["photons"] / 10
    assert page.evaluate("document.getElementById('render').naturalWidth") == second["width"]
    assert "pass 2" in page.text_content("#render-state") or "pass 3" in page.text_content("#render-state")
    page.screenshot(path=str(artifacts / "view-rendered.png"))
    assert watched.errors == []


def test_with_a_token_a_person_signs_in_once_and_the_view_works(tmp_path: Path, watched: Watched) -> None:
    """A service with a token (as beyond loopback): the view's address leads to the sign-in form; after the token
    is typed in, the same view opens, loads the model and its live event stream with the cookie alone (a browser
    cannot send the bearer header), with no console error."""
    token = "pages-token-of-at-least-16-chars"
    auth = {"Authorization": f"Bearer {token}"}
    with running_service(tmp_path / "token", env={"LUMENLINK_TOKEN": token}) as base, \
            httpx.Client(base_url=base, timeout=60, headers=auth) as http:
        scene = http.post("/scenes", json={"name": "signed-in room"}).json()["id"]
        floor = _mesh([[0, 0, 0], [4, 0, 0], [4, 4, 0], [0, 4, 0]], [[0, 1, 2], [0, 2, 3]])
        box = _mesh([[0, 0, 0], [0.4, 0, 0], [0, 0.4, 0]], [[0, 1, 2]])
        for gid, data in (floor, box):
            assert http.put(f"/geometries/{gid}", content=data,
                            headers={"content-type": "model/gltf-binary"}).status_code in (200, 201)
        assert http.put(f"/scenes/{scene}/document", json=_document(0, 0.6, floor[0], box[0])).status_code == 200
        page = watched.page
        page.goto(f"{base}/scenes/{scene}/view")
        assert page.url.startswith(f"{base}/sign-in?next=")
        page.fill("#token", "not the token at all")
        page.click("button[type=submit]")
        assert "not this service" in page.text_content("#problem")
        page.fill("#token", token)
        page.click("button[type=submit]")
        page.wait_for_url(f"{base}/scenes/{scene}/view")
        _wait(page, "window.lumenlink.ready && window.lumenlink.connection === 'live'")
        assert page.evaluate("window.lumenlink.counts()") == {"instances": 2, "sensors": 0}
        # the 401 of the wrong token's form is the one expected error the browser logs
        assert [e for e in watched.errors if "401" not in e] == []


def test_the_view_packs_a_light_guides_dots_and_switches_to_them(service: dict[str, Any], watched: Watched,
                                                                 artifacts: Path) -> None:
    """Issue 41 on the page: the demo guide's uniform dots (fill 1.0) listed with a "pack" button; a click runs the
    pack job (its iterations shown), and "use it" puts the packed element onto the guide."""
    from lumenlink import Client
    from lumenlink.guide_demo import DOT, PITCH, SIZE, _scene
    from lumenlink.guide_demo import GRID as GUIDE_GRID

    page, http = watched.page, service["http"]
    with Client(service["base"]) as ll:
        body = {"type": "microstructure", "feature": DOT, "relief": "bump",
                "layout": {"type": "density", "origin_mm": [0.0, 0.0], "size_mm": [SIZE[0], SIZE[1]],
                           "fill": [[1.0] * 24], "seed": 1, "pitch_mm": PITCH}}
        eid = ll.add_element(body)["id"]
        sid, _ = _scene(ll, http, "guide on the page")
        aid = ll.put_element(sid, "backlight/guide", eid, facing=[0, 0, -1])["id"]
        ll.add_sensor(sid, GUIDE_GRID)
    page.goto(f"{service['base']}/scenes/{sid}/view")
    _wait(page, "window.lumenlink?.ready")
    page.locator("#elements button", has_text="pack").click()
    page.locator("#elements .pack-use").wait_for(timeout=WAIT_MS)
    assert "min/max" in page.locator("#elements .pack-state").inner_text()
    page.screenshot(path=str(artifacts / "view-pack.png"))
    page.locator("#elements .pack-use").click()
    for _ in range(100):
        now = http.get(f"/scenes/{sid}/elements/{aid}").json()["body"]["element"]
        if now != eid:
            break
        page.wait_for_timeout(100)
    assert now != eid and http.get(f"/elements/{now}/pack").json()["packed_from"] == eid
    assert watched.errors == []


def test_the_view_links_a_gratings_order_efficiencies(service: dict[str, Any], watched: Watched,
                                                      artifacts: Path) -> None:
    """Issue 52 on the page: a grating on the guide's face is listed with a link to its orders' efficiencies
    against the wavelength (``orders.png``), which the service draws from the wave solution; no pack button (a
    grating has no dots)."""
    from lumenlink import Client
    from lumenlink.guide_demo import _scene

    page, http = watched.page, service["http"]
    grating = {"type": "grating", "profile": {"shape": "lamellar", "fill": 0.5}, "period_um": 1.0, "depth_um": 0.3,
               "ridge": None, "substrate_ior": 1.5, "wavelengths_nm": [450, 650], "wavelength_count": 3,
               "angles": {"polar_deg": [0, 30], "azimuth_deg": [0]}, "orders": 6}
    with Client(service["base"]) as ll:
        eid = ll.add_element(grating)["id"]
        sid, _ = _scene(ll, http, "grating on the page")
        ll.put_element(sid, "backlight/guide", eid, facing=[0, 0, 1])
    page.goto(f"{service['base']}/scenes/{sid}/view")
    _wait(page, "window.lumenlink?.ready")
    link = page.locator("#elements a.grating-orders")
    link.wait_for(timeout=WAIT_MS)
    href = link.get_attribute("href")
    assert href == f"/elements/{eid}/orders.png"
    png = http.get(href)
    assert png.status_code == 200 and png.content[:4] == b"\x89PNG"
    assert page.locator("#elements button", has_text="pack").count() == 0
    page.screenshot(path=str(artifacts / "view-grating.png"))
    assert watched.errors == []
