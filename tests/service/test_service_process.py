"""The service as it runs: a real `lumenlink serve` (uvicorn) on a free loopback port, SQLite in a temp dir.

Three process starts in all: one shared by the HTTP and concurrency tests, two for the restart.
"""

from __future__ import annotations

import threading

import httpx
import pytest
from service_helpers import car_document, glb, grid_mesh, translation, uid
from service_process import running_service


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    with running_service(tmp_path_factory.mktemp("served"), env={"LUMENLINK_WARM_KERNELS": "true"}) as url:
        yield url


@pytest.fixture(scope="module")
def meshes():
    return {"body": glb(*grid_mesh(2)), "wheel": glb(*grid_mesh(3, z=1.0))}


def upload(c: httpx.Client, meshes) -> None:
    ids = [gid for gid, _ in meshes.values()]
    missing = c.post("/geometries/missing", json={"ids": ids}).json()["missing"]
    for gid, data in meshes.values():
        if gid in missing:
            r = c.put(f"/geometries/{gid}", content=data, headers={"content-type": "model/gltf-binary"})
            assert r.status_code == 201, r.text


def test_push_over_http(server, meshes) -> None:
    with httpx.Client(base_url=server, timeout=60) as c:
        health = c.get("/health").json()
        assert health["status"] == "ok"
        assert health["kernels"]["state"] in ("warming", "ready")   # `lumenlink serve` compiles them at start
        upload(c, meshes)
        assert c.post("/geometries/missing", json={"ids": [g for g, _ in meshes.values()]}).json() == {"missing": []}
        sid = c.post("/scenes", json={"name": "http"}).json()["id"]
        doc = car_document(meshes["body"][0], meshes["wheel"][0])
        a = c.put(f"/scenes/{sid}/document", json=doc).json()
        assert a["revision"] == 1 and len(a["added"]) == 8
        doc["base_revision"] = 1
        doc["nodes"][2]["transform"] = translation(30, 0, 0)
        a = c.put(f"/scenes/{sid}/document", json=doc).json()
        assert a["moved"] == [uid(2)] and a["blas_built"] == 0 and a["revision"] == 2
        r = c.put(f"/scenes/{sid}/document", content=b"{oops", headers={"content-type": "application/json"})
        assert r.status_code == 400 and r.headers["content-type"] == "application/problem+json"
        assert c.get(f"/scenes/{sid}").json()["revision"] == 2


def test_two_clients_on_the_same_base_revision(server, meshes) -> None:
    """Both push on revision 1 at once: exactly one wins, the other gets 409, nothing is lost."""
    with httpx.Client(base_url=server, timeout=60) as c:
        upload(c, meshes)
        sid = c.post("/scenes", json={"name": "race"}).json()["id"]
        doc = car_document(meshes["body"][0], meshes["wheel"][0])
        assert c.put(f"/scenes/{sid}/document", json=doc).status_code == 200
    answers: dict[str, httpx.Response] = {}
    barrier = threading.Barrier(2)

    def client(name: str, x: float) -> None:
        mine = car_document(meshes["body"][0], meshes["wheel"][0], base_revision=1, door_x=x)
        with httpx.Client(base_url=server, timeout=60) as c:
            barrier.wait()
            answers[name] = c.put(f"/scenes/{sid}/document", json=mine)

    threads = [threading.Thread(target=client, args=(n, x)) for n, x in (("a", 11.0), ("b", 22.0))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    codes = sorted(r.status_code for r in answers.values())
    assert codes == [200, 409], {k: r.text for k, r in answers.items()}
    winner = next(k for k, r in answers.items() if r.status_code == 200)
    loser = next(k for k, r in answers.items() if r.status_code == 409)
    assert answers[loser].json()["current_revision"] == 2
    with httpx.Client(base_url=server, timeout=60) as c:
        nodes = {n["uuid"]: n for n in c.get(f"/scenes/{sid}/nodes").json()}
        assert nodes[uid(2)]["transform"][3] == {"a": 11.0, "b": 22.0}[winner]
        # the loser rebases on revision 2 and pushes again: nothing is lost
        mine = car_document(meshes["body"][0], meshes["wheel"][0], base_revision=2,
                            door_x={"a": 11.0, "b": 22.0}[loser])
        a = c.put(f"/scenes/{sid}/document", json=mine).json()
        assert a["revision"] == 3 and a["moved"] == [uid(2)]


def test_restart_reloads_everything_without_rebuilding_bottom_levels(tmp_path) -> None:
    big = glb(*grid_mesh(24))  # 1152 triangles: above the tracer's cache threshold, so its BLAS is cached
    wheel = glb(*grid_mesh(20, z=1.0))  # 800 triangles
    doc = car_document(big[0], wheel[0])
    with running_service(tmp_path) as url, httpx.Client(base_url=url, timeout=60) as c:
        upload(c, {"big": big, "wheel": wheel})
        sid = c.post("/scenes", json={"name": "persist"}).json()["id"]
        first = c.put(f"/scenes/{sid}/document", json=doc).json()
        assert first["blas_built"] == 2
        c.put(f"/scenes/{sid}/materials/{uid(3)}", json={"type": "mirror", "reflectance": 0.7})
        light = c.post(f"/scenes/{sid}/lights", json={"type": "point", "position": [0, 0, 1], "flux_lm": 100,
                                                      "attached_to": uid(2)}).json()
        sensor = c.post(f"/scenes/{sid}/sensors", json={"type": "disk", "center": [0, 0, 0], "normal": [0, 0, 1],
                                                        "radius": 0.01}).json()
        obj = c.post(f"/scenes/{sid}/objects", json={"geometry": wheel[0], "transform": translation(0, 0, 5)}).json()
        gone = dict(doc, base_revision=1, nodes=[n for n in doc["nodes"] if n["uuid"] != uid(13)])
        c.put(f"/scenes/{sid}/materials/{uid(13)}", json={"type": "black"})
        c.put(f"/scenes/{sid}/document", json=gone)
        before = c.get(f"/scenes/{sid}").json()
        nodes_before = c.get(f"/scenes/{sid}/nodes").json()
    with running_service(tmp_path) as url, httpx.Client(base_url=url, timeout=60) as c:
        after = c.get(f"/scenes/{sid}").json()
        assert after["last_commit"]["blas_built"] == 0 and after["last_commit"]["blas_loaded"] == 2
        for key in ("revision", "nodes", "objects", "triangles", "geometries", "orphaned", "materials_assigned",
                    "default_material_instances", "lights", "sensors", "sim_objects"):
            assert after[key] == before[key], key
        assert after["orphaned"] == [{"kind": "material", "id": uid(13), "node": uid(13)}]
        nodes_after = c.get(f"/scenes/{sid}/nodes").json()
        key = lambda n: n["uuid"]  # noqa: E731
        strip = lambda ns: [{k: v for k, v in n.items() if k != "instance"} for n in sorted(ns, key=key)]  # noqa: E731
        assert strip(nodes_after) == strip(nodes_before)
        assert c.get(f"/scenes/{sid}/lights/{light['id']}").json()["body"]["attached_to"] == uid(2)
        assert c.get(f"/scenes/{sid}/sensors/{sensor['id']}").status_code == 200
        assert c.get(f"/scenes/{sid}/objects/{obj['id']}").status_code == 200
        # the restored uuid brings its material back, and pushes continue from the stored revision
        a = c.put(f"/scenes/{sid}/document", json=dict(doc, base_revision=2)).json()
        assert a["revision"] == 3 and a["added"] == [uid(13)] and a["blas_built"] == 0
        assert a["restored"] == [{"kind": "material", "id": uid(13), "node": uid(13)}]
