"""The pages' routes without a browser (issue 23): the API docs and the pages reference only assets the service
serves itself, and those answer 200; the view's state says where every instance is (metres) and what the last push
changed; the event stream refuses bad ids, sends what happened and ends when the service stops.

The browser side is tests/e2e/test_pages.py. The assets come from `make web` (npm ci in service/web): without
them these tests fail, saying so.
"""

from __future__ import annotations

import re
import sys
import threading
import time
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import httpx
import pytest
from service_helpers import glb, grid_mesh, make_client, node, translation, uid

from service.routes import pages

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from service_process import running_service  # noqa: E402

NO_ASSETS = f"the web assets are not installed ({pages.NODE_MODULES}): run `make web`"
UNKNOWN = "00000000-0000-4000-8000-00000000dead"


class _Refs(HTMLParser):
    """Every URL a page's tags load (script src, link href, img src) and the import map's targets."""

    def __init__(self) -> None:
        super().__init__()
        self.urls: list[str] = []
        self._in_importmap = False

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        if tag in ("script", "img") and a.get("src"):
            self.urls.append(str(a["src"]))
        if tag == "link" and a.get("href"):
            self.urls.append(str(a["href"]))
        self._in_importmap = tag == "script" and a.get("type") == "importmap"

    def handle_data(self, data: str) -> None:
        if self._in_importmap:
            self.urls += [u for u in re.findall(r'"(/static/[^"]+)"', data) if not u.endswith("/")]
            self._in_importmap = False


def _refs(html: str) -> list[str]:
    parser = _Refs()
    parser.feed(html)
    return parser.urls


@pytest.fixture
def client(tmp_path: Path) -> Any:
    with make_client(tmp_path) as c:
        yield c


def _scene(client: Any, length_unit: str = "m", name: str = "room") -> dict[str, str]:
    sid = client.post("/scenes", json={"name": name}).json()["id"]
    v, f = grid_mesh(n=2, size=2.0 if length_unit == "m" else 2000.0)
    gid, data = glb(v, f)
    assert client.put(f"/geometries/{gid}", content=data, headers={"content-type": "model/gltf-binary"}
                      ).status_code in (200, 201)
    step = 1.0 if length_unit == "m" else 1000.0
    doc = {"base_revision": 0, "length_unit": length_unit,
           "nodes": [node(uid(0), None, "room"), node(uid(1), uid(0), "floor", translation(-step, -step, 0), gid),
                     node(uid(2), uid(0), "tile", translation(step, 0, 0), gid)]}
    assert client.put(f"/scenes/{sid}/document", json=doc).status_code == 200
    return {"id": sid, "gid": gid}


@pytest.mark.parametrize("path", ["/docs", "/redoc"])
def test_api_docs_load_only_local_assets_and_they_answer(client: Any, path: str) -> None:
    assert pages.REQUIRED["swagger-ui-dist"].is_file() and pages.REQUIRED["redoc"].is_file(), NO_ASSETS
    r = client.get(path)
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/html")
    assert "cdn." not in r.text and "googleapis" not in r.text
    urls = _refs(r.text)
    assert len([u for u in urls if u.endswith(".js")]) >= 1
    for url in urls:
        assert url.startswith("/") and not url.startswith("//"), f"{path} loads {url} from elsewhere"
        asset = client.get(url)
        assert asset.status_code == 200, url
        if url.endswith(".js"):
            assert "javascript" in asset.headers["content-type"]
            assert b"cdn.redoc.ly" not in asset.content   # ReDoc's bundle would draw Redocly's logo from their CDN
    assert client.get("/docs/oauth2-redirect").status_code == 200
    assert client.get("/openapi.json").status_code == 200


def test_the_view_page_and_its_modules_are_served_here(client: Any) -> None:
    assert pages.REQUIRED["three"].is_file(), NO_ASSETS
    s = _scene(client)
    r = client.get(f"/scenes/{s['id']}/view")
    assert r.status_code == 200 and f'data-scene="{s["id"]}"' in r.text
    urls = _refs(r.text)
    assert "/static/three/build/three.module.js" in urls and "/static/app/main.js" in urls
    modules = ["/static/app/main.js", "/static/app/scene3d.js", "/static/app/colour.js", "/static/app/api.js",
               "/static/three/build/three.module.js", "/static/three/addons/loaders/GLTFLoader.js",
               "/static/three/addons/controls/OrbitControls.js"]
    for url in urls + modules:
        assert url.startswith("/static/"), url
        asset = client.get(url)
        assert asset.status_code == 200, url
    for module in modules[:4]:   # our modules import only relative files and the import map's names
        imports = re.findall(r'^import .* from "([^"]+)";$', client.get(module).text, flags=re.M)
        assert all(i.startswith("./") or i == "three" or i.startswith("three/addons/") for i in imports), imports
    assert client.get("/static/app/../../config.py").status_code == 404   # nothing outside the asset directories


def test_index_lists_the_scenes_with_names_escaped(client: Any) -> None:
    a = client.post("/scenes", json={"name": "<b>lobby</b> & hall"}).json()["id"]
    r = client.get("/")
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/html")
    assert f'<a href="/scenes/{a}/view">&lt;b&gt;lobby&lt;/b&gt; &amp; hall</a>' in r.text
    assert "<b>lobby" not in r.text


def test_bad_scene_ids_get_problems(client: Any) -> None:
    for route in ("view", "view/state", "events"):
        r = client.get(f"/scenes/{UNKNOWN}/{route}")
        assert r.status_code == 404 and r.headers["content-type"] == "application/problem+json", route
        r = client.get(f"/scenes/not-a-uuid/{route}")
        assert r.status_code == 422 and "scene_id" in r.text, route


def test_events_refused_when_too_many_streams_are_open(client: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    s = _scene(client)
    monkeypatch.setattr("service.events.MAX_STREAMS", 0)
    r = client.get(f"/scenes/{s['id']}/events")
    assert r.status_code == 503 and int(r.headers["retry-after"]) >= 1


def test_view_state_places_instances_in_metres_and_keeps_the_last_push(client: Any) -> None:
    s = _scene(client, length_unit="mm")
    state = client.get(f"/scenes/{s['id']}/view/state").json()
    assert state["scene"]["revision"] == 1 and state["scene"]["length_unit"] == "mm"
    by_node = {r["node"]: r for r in state["instances"]}
    assert set(by_node) == {uid(1), uid(2)} and all(r["geometry"] == s["gid"] for r in by_node.values())
    # the mesh is in mm: world_from_mesh scales by 1e-3 and translates in metres
    m = by_node[uid(2)]["matrix"]
    assert m[0] == pytest.approx(1e-3) and m[3] == pytest.approx(1.0) and m[7] == pytest.approx(0.0)
    assert by_node[uid(1)]["matrix"][3] == pytest.approx(-1.0)
    assert [n["path"] for n in state["nodes"]] == ["room", "room/floor", "room/tile"]
    assert state["last_push"]["counts"]["added"] == 3 and sorted(state["last_push"]["added"]) == [uid(0), uid(1),
                                                                                                    uid(2)]
    assert state["sensors"] == [] and state["lights"] == [] and state["jobs"] == []

    moved = {"base_revision": 1, "length_unit": "mm",
             "nodes": [node(uid(0), None, "room"),
                       node(uid(1), uid(0), "floor", translation(-1000, -1000, 0), s["gid"]),
                       node(uid(2), uid(0), "tile", translation(2500, 0, 0), s["gid"])]}
    assert client.put(f"/scenes/{s['id']}/document?dry_run=true", json=moved).status_code == 200
    assert client.get(f"/scenes/{s['id']}/view/state").json()["last_push"]["revision"] == 1   # a dry run is no push
    assert client.put(f"/scenes/{s['id']}/document", json=moved).status_code == 200
    state = client.get(f"/scenes/{s['id']}/view/state").json()
    push = state["last_push"]
    assert push["revision"] == 2 and push["moved"] == [uid(2)] and push["added"] == []
    assert push["counts"] == {"added": 0, "moved": 1, "geometry_changed": 0, "removed": 0, "renamed": 0}
    assert {r["node"]: r for r in state["instances"]}[uid(2)]["matrix"][3] == pytest.approx(2.5)


def test_view_state_carries_lights_sensors_materials_and_grid_results(client: Any) -> None:
    s = _scene(client)
    sid = s["id"]
    assert client.put(f"/scenes/{sid}/materials/{uid(0)}", json={"type": "lambertian", "reflectance": 0.6}
                      ).status_code == 200
    assert client.post(f"/scenes/{sid}/lights", json={"type": "goniometric", "name": "downlight", "format": "ies",
                                                      "position": [0, 0, 2],
                                                      "data": (Path(__file__).parents[2] / "lumenlink" / "data" /
                                                               "rab_dled6r8y_7.ies").read_text()}).status_code == 201
    sensor = client.post(f"/scenes/{sid}/sensors", json={"type": "grid", "name": "grid", "origin": [-1, -1, 0],
                                                         "u": [2, 0, 0], "v": [0, 2, 0], "nu": 2, "nv": 2}).json()["id"]
    state = client.get(f"/scenes/{sid}/view/state").json()
    assert all(r["material"] == {"type": "lambertian", "reflectance": 0.6} for r in state["instances"])  # inherited
    [light] = state["lights"]
    assert light["name"] == "downlight" and light["position"] == [0, 0, 2] and "data" not in light
    [grid] = state["sensors"]
    assert grid["id"] == sensor and grid["name"] == "grid" and grid["result"] is None and grid["nu"] == 2
    r = client.post(f"/scenes/{sid}/sensors/{sensor}/simulate", json={"max_photons": 5_000, "seed": 1})
    assert r.status_code == 200, r.text
    result = client.get(f"/scenes/{sid}/view/state").json()["sensors"][0]["result"]
    assert result["lux"] == r.json()["lux"] and result["stderr"] == r.json()["stderr"]
    assert result["photons"] == r.json()["photons"] and result["revision"] == 1


def _events(lines: Any, until: str, seen: list[tuple[str, Any]]) -> None:
    """Read server-sent events into `seen` until one named `until` arrives."""
    import json

    name = None
    for line in lines:
        if line.startswith("event: "):
            name = line[7:]
        elif line.startswith("data: ") and name is not None:
            seen.append((name, json.loads(line[6:])))
            if name == until:
                return
            name = None


def test_event_stream_through_a_real_process(tmp_path: Path) -> None:
    seen: list[tuple[str, Any]] = []
    with running_service(tmp_path) as base, httpx.Client(base_url=base, timeout=30) as http:
        s = _scene(http)
        with http.stream("GET", f"/scenes/{s['id']}/events") as stream:
            assert stream.status_code == 200 and stream.headers["content-type"].startswith("text/event-stream")
            lines = stream.iter_lines()
            _events(lines, "hello", seen)
            assert seen == [("hello", {"revision": 1})]
            doc = {"base_revision": 1, "length_unit": "m",
                   "nodes": [node(uid(0), None, "room"),
                             node(uid(1), uid(0), "floor", translation(-1, -1, 0), s["gid"]),
                             node(uid(2), uid(0), "tile", translation(1, 1, 0), s["gid"])]}
            assert http.put(f"/scenes/{s['id']}/document", json=doc).status_code == 200
            _events(lines, "push", seen)
            assert ("scene", {"revision": 2}) in seen
            assert seen[-1] == ("push", {"revision": 2, "counts": {"added": 0, "moved": 1, "geometry_changed": 0,
                                                                   "removed": 0, "renamed": 0}})
            assert http.put(f"/scenes/{s['id']}/materials/{uid(1)}", json={"type": "black"}).status_code == 200
            _events(lines, "scene", seen)   # an assignment keeps the revision and still tells the page
            assert seen[-1] == ("scene", {"revision": 2})


def test_shutdown_ends_open_event_streams(tmp_path: Path) -> None:
    """An open stream does not hold the service up when it is asked to stop (uvicorn waits for open responses)."""
    lines_read: list[str] = []
    done = threading.Event()
    with running_service(tmp_path) as base, httpx.Client(base_url=base, timeout=30) as http:
        s = _scene(http)

        def follow() -> None:
            try:
                with httpx.stream("GET", f"{base}/scenes/{s['id']}/events", timeout=60) as r:
                    for line in r.iter_lines():
                        lines_read.append(line)
            except httpx.HTTPError as exc:
                lines_read.append(f"error: {exc!r}")
            done.set()

        threading.Thread(target=follow, daemon=True).start()
        deadline = time.monotonic() + 10
        while not any(line.startswith("event: hello") for line in lines_read) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert any(line.startswith("event: hello") for line in lines_read)
        t0 = time.monotonic()
    stopped = time.monotonic() - t0
    assert done.wait(5), "the stream did not end with the service"
    assert stopped < 10, f"the service took {stopped:.1f} s to stop with a stream open (15 s means SIGKILL)"
    assert not any(line.startswith("error") for line in lines_read), lines_read
    assert "Application shutdown complete" in (tmp_path / "service.log").read_text()


def test_with_a_token_the_docs_and_their_assets_stay_open_and_the_pages_do_not(tmp_path: Path) -> None:
    token = "a-token-of-at-least-16-characters"
    with make_client(tmp_path, token=token) as client:
        for path in ("/docs", "/redoc", "/static/swagger-ui/swagger-ui-bundle.js", "/static/redoc/redoc.standalone.js",
                     "/static/app/main.js"):
            assert client.get(path).status_code == 200, path   # no data in them; a browser sends no token
        for path in ("/", f"/scenes/{UNKNOWN}/view/state", "/scenes"):
            assert client.get(path).status_code == 401, path   # the scenes' names and contents are data
        assert client.get("/", headers={"Authorization": f"Bearer {token}"}).status_code == 200
