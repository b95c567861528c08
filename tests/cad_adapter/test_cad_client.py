"""The REST client and the push CLI against an in-memory fake of the service (httpx.MockTransport)."""

from __future__ import annotations

import json
import re
import uuid

import httpx
import pytest
from cad_helpers import COARSE, car

import cad_adapter
from cad_adapter import cli
from cad_adapter.client import Pusher
from cad_adapter.errors import PushError, RevisionConflict, ServiceUnavailable
from cad_adapter.glb import decode_glb_faces
from cad_adapter.step_uuid import write_step
from tests.hash_counting import counted_geometry_hashes
from tracer.geometry_id import geometry_id


class FakeService:
    """Just enough of docs/DESIGN.md's REST contract, checking what the adapter sends."""

    def __init__(self) -> None:
        self.scenes: dict[str, dict] = {}
        self.meshes: set[str] = set()
        self.calls: list[tuple[str, str]] = []
        self.documents: list[dict] = []
        self.bump_before_push = False  # someone else pushes between our GET and our PUT
        self.check_ids = True  # hash each upload as the service does (off where a test counts the adapter's hashes)

    def __call__(self, request: httpx.Request) -> httpx.Response:
        path, method = request.url.path, request.method
        self.calls.append((method, path))
        if (method, path) == ("GET", "/scenes"):
            listing = [{k: s[k] for k in ("id", "name", "revision")} for s in self.scenes.values()]
            return httpx.Response(200, json=listing)
        if (method, path) == ("POST", "/scenes"):
            sid = str(uuid.uuid4())
            self.scenes[sid] = {"id": sid, "name": json.loads(request.content)["name"], "revision": 0}
            return httpx.Response(201, json=self.scenes[sid])
        if (method, path) == ("POST", "/geometries/missing"):
            ids = json.loads(request.content)["ids"]
            return httpx.Response(200, json={"missing": [i for i in ids if i not in self.meshes]})
        m = re.fullmatch(r"/geometries/([0-9a-f]{64})", path)
        if m and method == "PUT":
            assert request.headers["content-type"] == "model/gltf-binary"
            if self.check_ids and geometry_id(*decode_glb_faces(request.content)) != m.group(1):
                return httpx.Response(400, json={"title": "Bad Request", "detail": "hash mismatch"})
            self.meshes.add(m.group(1))
            return httpx.Response(201, json={"id": m.group(1)})
        m = re.fullmatch(r"/scenes/([^/]+)(/document|/nodes)?", path)
        if m and m.group(1) in self.scenes:
            scene = self.scenes[m.group(1)]
            if method == "GET" and not m.group(2):
                return httpx.Response(200, json=scene)
            if method == "GET" and m.group(2) == "/nodes":  # the last pushed tree (records as the service keeps)
                last = next((d for d in reversed(self.documents) if d.get("_scene") == scene["id"]), None)
                return httpx.Response(200, json=[] if last is None else [
                    {**n, "product": (last.get("identity") or {}).get(n["uuid"], {}).get("product"),
                     "signature": (last.get("identity") or {}).get(n["uuid"], {}).get("signature")}
                    for n in last["nodes"]])
            if method == "PUT" and m.group(2):
                body = json.loads(request.content)
                if self.bump_before_push:
                    scene["revision"] += 1
                if body["base_revision"] != scene["revision"]:
                    return httpx.Response(409, json={"title": "Conflict", "detail": "stale base_revision"},
                                          headers={"content-type": "application/problem+json"})
                missing = [n["geometry"] for n in body["nodes"] if n["geometry"] and n["geometry"] not in self.meshes]
                if missing:
                    return httpx.Response(422, json={"title": "Unprocessable",
                                                     "detail": f"unknown geometry {missing[0]}"},
                                          headers={"content-type": "application/problem+json"})
                self.documents.append({**body, "_scene": scene["id"]})
                scene["revision"] += 1
                return httpx.Response(200, json={"scene": scene["id"], "revision": scene["revision"],
                                                 "base_revision": body["base_revision"], "added": [], "removed": [],
                                                 "moved": [], "geometry_changed": [], "renamed": [], "unchanged": 0,
                                                 "seconds": {"total": 0.001}})
        return httpx.Response(404, json={"title": "Not Found", "detail": path})

    def count(self, method: str, pattern: str) -> int:
        return sum(1 for m, p in self.calls if m == method and re.fullmatch(pattern, p))


@pytest.fixture
def fake() -> FakeService:
    return FakeService()


def pusher(fake: FakeService) -> Pusher:
    return Pusher("http://fake", transport=httpx.MockTransport(fake))


def doc_and_tess(radius: float = 120.0, sidecar=None):
    doc = cad_adapter.read_document(car(0.0, radius), sidecar=sidecar)
    return doc, cad_adapter.tessellate(doc, **COARSE)


def test_first_push_creates_the_scene_and_uploads_each_distinct_mesh_once(fake, tmp_path) -> None:
    doc, tess = doc_and_tess(sidecar=tmp_path / "s.json")
    with pusher(fake) as p:
        result = p.push(doc, tess, scene="car")
    assert result.created_scene and result.geometries == 7 and result.uploaded == 7
    assert fake.count("PUT", r"/geometries/.*") == 7  # four wheels, one upload
    assert fake.documents[0]["base_revision"] == 0
    assert result.answer["revision"] == 1
    # the same document again: nothing to upload, based on the revision just made
    with pusher(fake) as p:
        again = p.push(*doc_and_tess(sidecar=tmp_path / "s.json"), scene="car")
    assert not again.created_scene and again.uploaded == 0
    assert fake.documents[1]["base_revision"] == 1
    assert fake.documents[1]["nodes"] == fake.documents[0]["nodes"]


def test_one_part_edit_uploads_one_mesh(fake, tmp_path) -> None:
    with pusher(fake) as p:
        p.push(*doc_and_tess(sidecar=tmp_path / "s.json"), scene="car")
        edited = p.push(*doc_and_tess(150.0, sidecar=tmp_path / "s.json"), scene="car")
    assert edited.uploaded == 1
    before, after = ({n["uuid"]: n["geometry"] for n in d["nodes"]} for d in fake.documents)
    assert before.keys() == after.keys()
    assert [u for u in before if before[u] != after[u]] == [n["uuid"] for n in fake.documents[1]["nodes"]
                                                              if n["name"] == "lens"]


def test_conflict_rereads_the_revision_and_never_retries(fake) -> None:
    fake.bump_before_push = True
    with pusher(fake) as p, pytest.raises(RevisionConflict, match="now at revision 1") as err:
        p.push(*doc_and_tess(), scene="car")
    assert err.value.current_revision == 1
    assert fake.count("PUT", r"/scenes/.*/document") == 1
    assert not fake.documents


def test_server_down_is_a_clear_error() -> None:
    def refuse(request: httpx.Request) -> httpx.Response:
        raise httpx.ConnectError("connection refused", request=request)

    with Pusher("http://127.0.0.1:9", transport=httpx.MockTransport(refuse)) as p, \
            pytest.raises(ServiceUnavailable, match="cannot reach the service at http://127.0.0.1:9"):
        p.push(*doc_and_tess(), scene="car")


def test_timeout_is_unavailable() -> None:
    def slow(request: httpx.Request) -> httpx.Response:
        raise httpx.ReadTimeout("timed out", request=request)

    with Pusher("http://x", transport=httpx.MockTransport(slow)) as p, \
            pytest.raises(ServiceUnavailable, match="in time"):
        p.scene_by_name("car")


def test_problem_details_reach_the_user(fake) -> None:
    def reject(request: httpx.Request) -> httpx.Response:
        if request.url.path.endswith("/document"):
            return httpx.Response(422, json={"title": "Unprocessable Entity",
                                             "detail": "node 3: transform is singular"})
        return fake(request)

    with Pusher("http://fake", transport=httpx.MockTransport(reject)) as p, \
            pytest.raises(PushError, match="HTTP 422: Unprocessable Entity: node 3: transform is singular"):
        p.push(*doc_and_tess(), scene="car")


def test_one_client_one_error_hierarchy(fake) -> None:
    """The adapter's push errors are the service client's errors: the same refusal reads the same through
    `lumenlink.Client` and `Pusher`, with the problem and status on both, and a dead service is one class."""
    import lumenlink
    from lumenlink.http import ServiceClient

    problem = {"title": "Unprocessable Entity", "detail": "the listing is refused", "status": 422}

    def reject(request: httpx.Request) -> httpx.Response:
        return httpx.Response(422, json=problem, headers={"content-type": "application/problem+json"})

    with Pusher("http://fake", transport=httpx.MockTransport(reject)) as p, pytest.raises(PushError) as pushed:
        p.scene_by_name("car")
    with lumenlink.Client("http://fake", transport=httpx.MockTransport(reject)) as ll, \
            pytest.raises(lumenlink.LumenLinkError) as listed:
        ll.scenes()
    assert isinstance(p, ServiceClient) and isinstance(ll, ServiceClient)
    assert isinstance(pushed.value, lumenlink.LumenLinkError) and isinstance(pushed.value, cad_adapter.CadAdapterError)
    assert str(pushed.value) == str(listed.value) == ("listing scenes failed: HTTP 422: Unprocessable Entity: "
                                                      "the listing is refused")
    for err in (pushed.value, listed.value):
        assert (err.status, err.problem, err.usage) == (422, problem, True)

    def refuse(request: httpx.Request) -> httpx.Response:
        raise httpx.ConnectError("connection refused", request=request)

    with Pusher("http://127.0.0.1:9", transport=httpx.MockTransport(refuse)) as p, \
            pytest.raises(lumenlink.ServiceUnreachable) as down:
        p.scene_by_name("car")
    assert isinstance(down.value, ServiceUnavailable)

    fake.bump_before_push = True
    with pusher(fake) as p, pytest.raises(lumenlink.LumenLinkError) as conflict:
        p.push(*doc_and_tess(), scene="car")
    assert isinstance(conflict.value, RevisionConflict) and conflict.value.status == 409 and not conflict.value.usage


@pytest.mark.parametrize("server", ["", "ftp://x", "127.0.0.1:8000"])
def test_bad_server_url(server) -> None:
    with pytest.raises(PushError, match="http"):
        Pusher(server)


def test_empty_scene_name(fake) -> None:
    with pusher(fake) as p, pytest.raises(PushError, match="scene name"):
        p.find_or_create_scene("  ")


# ---------------------------------------------------------------- the CLI functions


@pytest.fixture(scope="module")
def car_step(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    doc = cad_adapter.read_document(car(), write_sidecar=False)
    return write_step(doc, d / "car.step")


def test_cli_push_prints_summary_and_json(fake, car_step, tmp_path, capsys) -> None:
    t = httpx.MockTransport(fake)
    code = cli.push(car_step, "car", "http://fake", linear=1.0, angular=0.8, transport=t, cache_dir=tmp_path)
    out = capsys.readouterr()
    assert code == 0
    assert "revision 0 -> 1 (scene created)" in out.out and "7 uploaded" in out.out
    code = cli.push(car_step, "car", "http://fake", linear=1.0, angular=0.8, json_out=True, transport=t,
                    cache_dir=tmp_path)
    out = capsys.readouterr()
    assert code == 0 and json.loads(out.out)["revision"] == 2
    assert "from cache" not in out.out


def test_cli_exit_codes(fake, car_step, tmp_path, capsys) -> None:
    t = httpx.MockTransport(fake)
    assert cli.push(tmp_path / "nope.step", "car", "http://fake", transport=t, cache_dir=tmp_path) == cli.EXIT_INPUT
    assert "no such file" in capsys.readouterr().err
    assert cli.push(car_step, "car", "http://fake", linear=-1.0, transport=t, cache_dir=tmp_path) == cli.EXIT_INPUT
    fake.bump_before_push = True
    assert cli.push(car_step, "car", "http://fake", linear=1.0, angular=0.8, transport=t,
                    cache_dir=tmp_path) == cli.EXIT_CONFLICT
    assert "nothing was pushed" in capsys.readouterr().err

    def refuse(request: httpx.Request) -> httpx.Response:
        raise httpx.ConnectError("refused", request=request)

    assert cli.push(car_step, "car", "http://127.0.0.1:9", linear=1.0, angular=0.8,
                    transport=httpx.MockTransport(refuse), cache_dir=tmp_path) == cli.EXIT_UNREACHABLE
    assert "lumenlink serve" in capsys.readouterr().err


def test_watch_pushes_on_change_debounced(fake, tmp_path) -> None:
    import threading
    import time

    step = tmp_path / "car.step"
    doc = cad_adapter.read_document(car(), sidecar=tmp_path / "ids.json")
    write_step(doc, step)
    edited = tmp_path / "edited.step"
    write_step(cad_adapter.read_document(car(0.0, 150.0), sidecar=tmp_path / "ids.json"), edited)
    codes: list[int] = []
    t = threading.Thread(target=lambda: codes.append(cli.watch(
        step, "car", "http://fake", linear=1.0, angular=0.8, debounce=1.0, poll=0.02, max_pushes=2, timeout=120,
        transport=httpx.MockTransport(fake), cache_dir=tmp_path / "cache")))
    t.start()
    deadline = time.monotonic() + 60
    while not fake.documents:
        assert time.monotonic() < deadline
        time.sleep(0.05)
    # a save in two steps (truncate, then write): the debounce waits for the file to settle
    step.write_text("")
    time.sleep(0.05)
    step.write_bytes(edited.read_bytes())
    t.join(timeout=120)
    assert codes == [0] and len(fake.documents) == 2
    before, after = ({n["uuid"]: n["geometry"] for n in d["nodes"]} for d in fake.documents)
    assert sum(before[u] != after[u] for u in before) == 1


def test_a_push_hashes_each_mesh_once(fake, car_step, tmp_path, monkeypatch) -> None:
    """`lumenlink push` (read, identify, tessellate, upload, push) computes each distinct mesh's geometry id once:
    the upload and the pushed tree use the id tessellation made. From a disk cache the mesh is hashed once too
    (checked against the id stored beside it)."""
    fake.check_ids = False  # the fake service's own check would count here
    t = httpx.MockTransport(fake)
    hashes = counted_geometry_hashes(monkeypatch)
    result = cli.push_file(car_step, "car", "http://fake", 1.0, 0.8, transport=t,
                           cache=cad_adapter.TessellationCache(tmp_path / "cache"))[0]
    assert result.geometries == 7 and result.uploaded == 7 and fake.count("PUT", r"/geometries/.*") == 7
    assert len(hashes) == 7
    hashes.clear()
    again = cli.push_file(car_step, "car", "http://fake", 1.0, 0.8, transport=t,
                          cache=cad_adapter.TessellationCache(tmp_path / "cache"))[0]
    assert again.uploaded == 0 and len(hashes) == 7


def test_watch_bad_input(tmp_path) -> None:
    assert cli.watch(tmp_path / "none.step", "car", "http://fake", timeout=0) == cli.EXIT_INPUT
    (tmp_path / "x.step").write_text("x")
    assert cli.watch(tmp_path / "x.step", "car", "http://fake", debounce=-1, timeout=0) == cli.EXIT_INPUT
    assert cli.watch(tmp_path / "x.step", "car", "http://fake", angular=5.0, timeout=0) == cli.EXIT_INPUT
