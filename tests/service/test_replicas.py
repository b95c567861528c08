"""Several service processes on one PostgreSQL database (docs/DESIGN.md, "Beyond one machine").

A real PostgreSQL server (initdb into a temp dir, `tests/postgres_server.py`) and two real
`lumenlink serve` processes, A and B, on that database and on one shared data directory (the mesh
store and the BLAS cache: a shared volume, as deployed). What one process changes, the other sees
at its next request; two pushes on one base revision through the two: one wins, one gets 409.
"""

from __future__ import annotations

import contextlib
import threading

import httpx
import pytest
from postgres_server import postgres_server, why_not
from service_helpers import car_document, glb, grid_mesh, make_client, node, translation, uid
from service_process import running_service

pytestmark = pytest.mark.skipif(why_not() is not None, reason=f"no PostgreSQL server here: {why_not()}")


@pytest.fixture(scope="module")
def database():
    with postgres_server() as url:
        yield url


@pytest.fixture(scope="module")
def replicas(database, tmp_path_factory):
    """Two service processes on one database and one data directory: (A's base URL, B's, the data dir)."""
    shared = tmp_path_factory.mktemp("shared-volume")
    env = {"LUMENLINK_DATABASE_URL": database}
    with contextlib.ExitStack() as stack:
        a = stack.enter_context(running_service(shared, env=env, log_name="a.log"))
        # B answers the illuminance query: it compiles (or loads) the query kernels from the start, in a child
        # process, while the other tests run (`tracer.warmup`, as `lumenlink serve` does by default)
        b = stack.enter_context(running_service(shared, env={**env, "LUMENLINK_WARM_KERNELS": "true"},
                                                log_name="b.log"))
        yield a, b, shared


@pytest.fixture(scope="module")
def car():
    return {"body": glb(*grid_mesh(2)), "wheel": glb(*grid_mesh(3, z=1.0))}


def upload(c: httpx.Client, meshes: dict) -> None:
    for gid, data in meshes.values():
        r = c.put(f"/geometries/{gid}", content=data, headers={"content-type": "model/gltf-binary"})
        assert r.status_code in (200, 201), r.text


def nodes(c: httpx.Client, sid: str) -> list[dict]:
    """The scene's nodes without the tracer instance ids (each process numbers its own)."""
    r = c.get(f"/scenes/{sid}/nodes")
    assert r.status_code == 200, r.text
    return [{k: v for k, v in n.items() if k != "instance"} for n in r.json()]


def car_scene(a: httpx.Client, car: dict, name: str) -> str:
    upload(a, car)
    sid = a.post("/scenes", json={"name": name}).json()["id"]
    r = a.put(f"/scenes/{sid}/document", json=car_document(car["body"][0], car["wheel"][0]))
    assert r.status_code == 200 and r.json()["revision"] == 1, r.text
    return sid


def test_a_push_through_one_process_is_seen_by_the_other(replicas, car) -> None:
    url_a, url_b, _ = replicas
    with httpx.Client(base_url=url_a, timeout=60) as a, httpx.Client(base_url=url_b, timeout=60) as b:
        upload(a, car)
        # B knows the geometries A stored (the database), and finds their meshes (the shared data dir)
        ids = [gid for gid, _ in car.values()]
        assert b.post("/geometries/missing", json={"ids": ids}).json() == {"missing": []}
        assert b.get(f"/geometries/{car['body'][0]}").content == car["body"][1]
        sid = a.post("/scenes", json={"name": "seen"}).json()["id"]
        assert b.get(f"/scenes/{sid}").json()["revision"] == 0   # B holds revision 0 in memory now
        doc = car_document(car["body"][0], car["wheel"][0])
        assert a.put(f"/scenes/{sid}/document", json=doc).json()["revision"] == 1
        seen = b.get(f"/scenes/{sid}").json()
        assert seen["revision"] == 1 and seen["nodes"] == 8 and seen["objects"] == 6
        assert nodes(b, sid) == nodes(a, sid) and len(nodes(b, sid)) == 8
        # B pushes on the revision it learnt; A follows
        doc["base_revision"] = 1
        doc["nodes"][2]["transform"] = translation(30, 0, 0)
        r = b.put(f"/scenes/{sid}/document", json=doc)
        assert r.status_code == 200 and r.json()["revision"] == 2 and r.json()["moved"] == [uid(2)], r.text
        door = next(n for n in nodes(a, sid) if n["uuid"] == uid(2))
        assert door["transform"][3] == 30.0
        assert [x["revision"] for x in a.get(f"/scenes/{sid}/revisions").json()] == [1, 2]
        # a scene deleted through A is gone for B too
        assert a.delete(f"/scenes/{sid}").status_code == 204
        gone = b.get(f"/scenes/{sid}")
        assert gone.status_code == 404 and gone.headers["content-type"] == "application/problem+json"


def test_assignments_through_one_process_are_seen_by_the_other(replicas, car) -> None:
    url_a, url_b, _ = replicas
    with httpx.Client(base_url=url_a, timeout=60) as a, httpx.Client(base_url=url_b, timeout=60) as b:
        sid = car_scene(a, car, "assigned")
        assert a.get(f"/scenes/{sid}/materials").json() == []   # A holds the scene in memory, no material
        r = b.put(f"/scenes/{sid}/materials/{uid(3)}", json={"type": "mirror", "reflectance": 0.7})
        assert r.status_code == 200, r.text
        assert a.get(f"/scenes/{sid}/materials").json() == [
            {"node": uid(3), "material": {"type": "mirror", "reflectance": 0.7}, "orphaned": False}]
        summary = a.get(f"/scenes/{sid}").json()
        assert summary["revision"] == 1 and summary["materials_assigned"] == 1
        assert summary["default_material_instances"] == 6 - 4   # the axle's four wheels inherit the mirror
        light = a.post(f"/scenes/{sid}/lights", json={"type": "point", "position": [0, 0, 1], "flux_lm": 100,
                                                      "attached_to": uid(2)})
        assert light.status_code == 201, light.text
        lid = light.json()["id"]
        assert [x["id"] for x in b.get(f"/scenes/{sid}/lights").json()] == [lid]
        obj = b.post(f"/scenes/{sid}/objects", json={"geometry": car["wheel"][0], "transform": translation(0, 0, 5)})
        assert obj.status_code == 201, obj.text
        assert a.get(f"/scenes/{sid}").json()["objects"] == 7   # A placed B's object in its tracer scene
        assert b.delete(f"/scenes/{sid}/materials/{uid(3)}").status_code == 204
        assert b.delete(f"/scenes/{sid}/lights/{lid}").status_code == 204
        assert a.get(f"/scenes/{sid}/materials").json() == [] and a.get(f"/scenes/{sid}/lights").json() == []
        assert a.delete(f"/scenes/{sid}/objects/{obj.json()['id']}").status_code == 204
        assert b.get(f"/scenes/{sid}").json()["objects"] == 6
        # assignments keep the revision number
        assert a.get(f"/scenes/{sid}").json()["revision"] == b.get(f"/scenes/{sid}").json()["revision"] == 1


def test_two_pushes_on_one_base_revision_through_two_processes(replicas, car) -> None:
    """A and B both push on revision 1 at once: exactly one wins, the other gets 409 and changes nothing."""
    url_a, url_b, _ = replicas
    with httpx.Client(base_url=url_a, timeout=60) as a, httpx.Client(base_url=url_b, timeout=60) as b:
        sid = car_scene(a, car, "race")
        assert b.get(f"/scenes/{sid}").json()["revision"] == 1   # both hold revision 1 in memory
    answers: dict[str, httpx.Response] = {}
    barrier = threading.Barrier(2)
    door = {"a": 11.0, "b": 22.0}

    def push(name: str, url: str) -> None:
        mine = car_document(car["body"][0], car["wheel"][0], base_revision=1, door_x=door[name])
        with httpx.Client(base_url=url, timeout=60) as c:
            barrier.wait()
            answers[name] = c.put(f"/scenes/{sid}/document", json=mine)

    threads = [threading.Thread(target=push, args=(n, u)) for n, u in (("a", url_a), ("b", url_b))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    codes = sorted(r.status_code for r in answers.values())
    assert codes == [200, 409], {k: r.text for k, r in answers.items()}
    winner = next(k for k, r in answers.items() if r.status_code == 200)
    loser = next(k for k, r in answers.items() if r.status_code == 409)
    lost = answers[loser]
    assert lost.headers["content-type"] == "application/problem+json"
    assert lost.json()["status"] == 409 and lost.json()["current_revision"] == 2
    urls = {"a": url_a, "b": url_b}
    with httpx.Client(base_url=url_a, timeout=60) as a, httpx.Client(base_url=url_b, timeout=60) as b:
        for c in (a, b):   # both report the winner's revision and tree
            assert c.get(f"/scenes/{sid}").json()["revision"] == 2
            assert next(n for n in nodes(c, sid) if n["uuid"] == uid(2))["transform"][3] == door[winner]
            assert [x["revision"] for x in c.get(f"/scenes/{sid}/revisions").json()] == [1, 2]
        assert nodes(a, sid) == nodes(b, sid)
    # the loser's process rebases on revision 2 and pushes again: its memory followed the winner's push
    with httpx.Client(base_url=urls[loser], timeout=60) as c:
        mine = car_document(car["body"][0], car["wheel"][0], base_revision=2, door_x=door[loser])
        r = c.put(f"/scenes/{sid}/document", json=mine)
        assert r.status_code == 200, r.text
        assert r.json()["revision"] == 3 and r.json()["moved"] == [uid(2)] and r.json()["added"] == []
    with httpx.Client(base_url=urls[winner], timeout=60) as c:
        assert next(n for n in nodes(c, sid) if n["uuid"] == uid(2))["transform"][3] == door[loser]


def test_illuminance_through_one_process_after_a_push_through_the_other(replicas) -> None:
    """A black floor under a 100 cd point source 2 m up: 25 lx below it, through B; A then pushes a black plate
    between them, and B answers on the new revision: no light."""
    url_a, url_b, _ = replicas
    floor = glb(*grid_mesh(1, size=4.0))
    plate = glb(*grid_mesh(1, z=1.0, size=4.0))
    body = {"points": [[0.0, 0.0, 0.0]], "normals": [[0.0, 0.0, 1.0]], "radius": 0.01, "max_photons": 2000,
            "estimator": "backward", "seed": 1}
    doc = {"base_revision": 0, "length_unit": "m", "nodes": [
        node(uid(0), None, "room"), node(uid(1), uid(0), "floor", translation(-2.0, -2.0, 0.0), geometry=floor[0])]}
    with httpx.Client(base_url=url_a, timeout=120) as a, httpx.Client(base_url=url_b, timeout=120) as b:
        upload(a, {"floor": floor, "plate": plate})
        sid = a.post("/scenes", json={"name": "lit"}).json()["id"]
        assert a.put(f"/scenes/{sid}/document", json=doc).status_code == 200
        assert a.put(f"/scenes/{sid}/materials/{uid(0)}", json={"type": "black"}).status_code == 200
        assert a.post(f"/scenes/{sid}/lights", json={"type": "point", "position": [0.0, 0.0, 2.0],
                                                     "intensity_cd": 100.0}).status_code == 201
        r = b.post(f"/scenes/{sid}/illuminance", json=body)
        assert r.status_code == 200, r.text
        lit = r.json()
        assert lit["revision"] == 1 and lit["photons"] <= 2000
        assert lit["lux"][0] == pytest.approx(25.0, rel=0.05)   # I h / h^3: B sees A's light and black floor
        doc["base_revision"] = 1
        doc["nodes"].append(node(uid(2), uid(0), "plate", translation(-2.0, -2.0, 0.0), geometry=plate[0]))
        assert a.put(f"/scenes/{sid}/document", json=doc).json()["revision"] == 2
        r = b.post(f"/scenes/{sid}/illuminance", json=body)
        assert r.status_code == 200, r.text
        dark = r.json()
        assert dark["revision"] == 2 and dark["lux"] == [0.0]   # the plate (black, inherited) shades the point


def test_a_process_that_does_not_share_the_data_dir_says_so(replicas, car, database, tmp_path) -> None:
    """A third process on the same database but its own data directory has no mesh files: a clear 503, no 500."""
    url_a, _, _ = replicas
    with httpx.Client(base_url=url_a, timeout=60) as a:
        sid = car_scene(a, car, "elsewhere")
    with make_client(tmp_path / "own", database_url=database) as c:
        assert c.get("/scenes").status_code == 200
        r = c.get(f"/scenes/{sid}")
        assert r.status_code == 503 and r.headers["content-type"] == "application/problem+json", r.text
        assert "LUMENLINK_DATA_DIR" in r.json()["detail"] and r.json()["geometry"] in {g for g, _ in car.values()}


# ---------------------------------------------------------------- the races, made to happen
# Two scene managers in this process (stand-in tracer scenes) on the one database and mesh store: a hook runs
# the other process's change at the worst moment, between this one's checks and its guarded write.


@pytest.fixture(scope="module")
def managers(database, tmp_path_factory):
    from service_fakes import FakeScene

    from service.config import Settings
    from service.db import open_engine
    from service.meshes import MeshStore
    from service.state import SceneManager

    shared = tmp_path_factory.mktemp("managers")
    made = []
    for _ in range(2):
        settings = Settings(data_dir=shared, database_url=database)
        made.append(SceneManager(settings, open_engine(database), MeshStore(settings.mesh_dir), FakeScene))
    yield made
    for m in made:
        m.engine.dispose()


def stored_scene(a, b, car: dict, name: str) -> str:
    """A scene at revision 1 (the car) that both managers hold in memory."""
    import json

    for gid, data in car.values():
        a.put_geometry(gid, data)
    sid = a.create_scene(name)["id"]
    a.push(sid, json.dumps(car_document(car["body"][0], car["wheel"][0])).encode())
    assert b.state(sid).revision == 1
    return sid


def test_the_losing_push_changes_nothing_and_its_process_follows_the_winner(managers, car) -> None:
    import json

    from service.errors import Conflict

    a, b = managers
    sid = stored_scene(a, b, car, "lost push")
    doc = lambda x: json.dumps(car_document(car["body"][0], car["wheel"][0], base_revision=1, door_x=x)).encode()  # noqa: E731
    store = b.pushes._store

    def a_first(*args, **kwargs):   # B has checked, diffed and applied its push; A commits first
        a.push(sid, doc(11.0))
        return store(*args, **kwargs)

    b.pushes._store = a_first
    try:
        with pytest.raises(Conflict) as lost:
            b.push(sid, doc(22.0))
    finally:
        del b.pushes._store
    assert lost.value.extensions["current_revision"] == 2
    for m in (a, b):   # the database and both memories hold A's push, B's changed nothing
        state = m.state(sid)
        assert state.revision == 2
        assert state.tree.local[state.tree.index[uid(2)]][0, 3] == 11.0   # mm, as pushed
        door = state.tracer.inst[state.instances[uid(2)]][1]   # the tracer scene's instance: metres
        assert door[0, 3] == pytest.approx(11.0 * 1e-3) and len(state.tracer.inst) == 6
    assert [r["revision"] for r in b.revisions(sid)] == [1, 2]


def test_an_assignment_that_races_a_push_is_checked_again_on_the_new_tree(managers, car) -> None:
    import json

    from service.errors import NotFound

    a, b = managers
    sid = stored_scene(a, b, car, "raced assignment")
    bump = b.store._bump
    pushes = []   # what A pushes, once each, between B's checks and B's guarded write
    tries = []

    def a_first(conn, scene_id, revision, assign_revision):
        tries.append(revision)
        if pushes:
            a.push(sid, json.dumps(pushes.pop()).encode())
        return bump(conn, scene_id, revision, assign_revision)

    doc = car_document(car["body"][0], car["wheel"][0], base_revision=1)
    doc["nodes"] = [n for n in doc["nodes"] if n["uuid"] != uid(13)]   # revision 2: wheel 3 is gone
    pushes.append(doc)
    b.store._bump = a_first
    try:
        # B found wheel 3 in its tree, A removed it before B's write: tried again on revision 2, refused
        with pytest.raises(NotFound, match=uid(13)):
            b.set_material(sid, uid(13), {"type": "black"})
        assert tries == [1]
        pushes.append(car_document(car["body"][0], car["wheel"][0], base_revision=2, door_x=5.0))  # revision 3
        assert b.set_material(sid, uid(12), {"type": "black"})["node"] == uid(12)   # tried again: made
        assert tries == [1, 2, 3]
    finally:
        del b.store._bump
    assert [m["node"] for m in a.list_materials(sid)] == [uid(12)] == [m["node"] for m in b.list_materials(sid)]
    assert a.state(sid).revision == b.state(sid).revision == 3


def test_identity_records_pushed_alone_through_one_process_are_seen_by_the_other(managers, car) -> None:
    """A push that changes only the identity records keeps the revision; the other process serves them all the
    same (``assign_revision`` counts the change)."""
    import json

    a, b = managers
    sid = stored_scene(a, b, car, "identity")
    doc = car_document(car["body"][0], car["wheel"][0], base_revision=1)
    doc["identity"] = {uid(1): {"product": "BODY-01"}, uid(2): {"product": "DOOR-07"}}
    answer = a.push(sid, json.dumps(doc).encode())
    assert answer["revision"] == 1 and answer["moved"] == [] and answer["added"] == []
    products = {n["uuid"]: n["product"] for n in b.nodes(sid)}
    assert products[uid(1)] == "BODY-01" and products[uid(2)] == "DOOR-07" and products[uid(3)] is None
    assert b.state(sid).revision == 1
