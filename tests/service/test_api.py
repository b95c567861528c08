"""The REST contract through FastAPI's TestClient (same app, real tracer, real SQLite file in a temp dir).

The real uvicorn process is exercised in test_service_process.py; here the bulk of the endpoint
behaviour: pushes and their diffs, rebuild counts, assignments that survive pushes, orphans,
the live view the simulation reads.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from service_helpers import UNKNOWN_ID, car_document, glb, grid_mesh, make_client, node, translation, uid

PROBLEM = "application/problem+json"


@pytest.fixture(scope="module")
def meshes() -> dict[str, tuple[str, bytes]]:
    return {"body": glb(*grid_mesh(2)), "wheel": glb(*grid_mesh(3, z=1.0)), "other": glb(*grid_mesh(4, z=2.0))}


@pytest.fixture
def client(tmp_path, meshes):
    with make_client(tmp_path) as c:
        for gid, data in meshes.values():
            assert c.put(f"/geometries/{gid}", content=data).status_code == 201
        yield c


@pytest.fixture
def scene(client) -> str:
    return client.post("/scenes", json={"name": "car"}).json()["id"]


def push(client, scene: str, doc: dict, status: int = 200) -> dict:
    r = client.put(f"/scenes/{scene}/document", json=doc)
    assert r.status_code == status, r.text
    return r.json()


def car(meshes, **kw) -> dict:
    return car_document(meshes["body"][0], meshes["wheel"][0], **kw)


# ---------------------------------------------------------------- scenes and geometries


def test_scene_lifecycle(client) -> None:
    r = client.post("/scenes", json={"name": "a"})
    assert r.status_code == 201 and r.json()["revision"] == 0
    sid = r.json()["id"]
    assert client.post("/scenes", json={"name": "a"}).status_code == 409
    assert [s["name"] for s in client.get("/scenes").json()] == ["a"]
    summary = client.get(f"/scenes/{sid}").json()
    assert summary["revision"] == 0 and summary["objects"] == 0 and summary["orphaned"] == []
    assert client.delete(f"/scenes/{sid}").status_code == 204
    r = client.get(f"/scenes/{sid}")
    assert r.status_code == 404 and r.headers["content-type"] == PROBLEM


def test_geometry_upload_is_idempotent_and_served_back(client, meshes) -> None:
    gid, data = meshes["body"]
    r = client.put(f"/geometries/{gid}", content=data, headers={"content-type": "model/gltf-binary"})
    assert r.status_code == 200 and r.json()["created"] is False and r.json()["triangles"] == 8
    assert client.get(f"/geometries/{gid}").content == data
    unknown = "f" * 64
    r = client.post("/geometries/missing", json={"ids": [gid, unknown, unknown]})
    assert r.json() == {"missing": [unknown]}
    assert client.get(f"/geometries/{unknown}").status_code == 404


def test_health_and_docs(client) -> None:
    assert client.get("/health").json() == {"status": "ok", "kernels": {"state": "not warmed"}}
    assert client.get("/docs").status_code == 200
    paths = client.get("/openapi.json").json()["paths"]
    assert "/scenes/{scene_id}/document" in paths and "/geometries/{gid}" in paths


# ---------------------------------------------------------------- pushes


def test_first_push_adds_everything_and_builds_each_geometry_once(client, scene, meshes) -> None:
    a = push(client, scene, car(meshes))
    assert a["revision"] == 1 and len(a["added"]) == 8 and a["unchanged"] == 0
    assert a["blas_built"] + a["blas_loaded"] == 2  # two distinct meshes, six instances
    assert a["instances"] == 6
    assert set(a["seconds"]) >= {"validate", "diff", "blas", "tlas", "store", "total"}
    s = client.get(f"/scenes/{scene}").json()
    assert s["objects"] == 6 and s["geometries"] == 2 and s["triangles"] == 2 * 8 + 4 * 18
    assert s["default_material_instances"] == 6


def test_identical_repush_is_an_empty_200(client, scene, meshes) -> None:
    push(client, scene, car(meshes))
    a = push(client, scene, car(meshes, base_revision=1))
    assert a["revision"] == 1 and a["unchanged"] == 8 and a["blas_built"] == 0
    assert all(a[k] == [] for k in ("added", "removed", "moved", "geometry_changed", "renamed"))
    assert client.get(f"/scenes/{scene}").json()["revision"] == 1


def test_retried_push_with_the_old_base_is_harmless(client, scene, meshes) -> None:
    push(client, scene, car(meshes))
    a = push(client, scene, car(meshes, base_revision=0))  # the same tree again, as a retry would
    assert a["revision"] == 1 and a["added"] == []


def test_moving_a_part_is_top_level_only(client, scene, meshes) -> None:
    push(client, scene, car(meshes))
    a = push(client, scene, car(meshes, base_revision=1, door_x=50.0))
    assert a["moved"] == [uid(2)] and a["unchanged"] == 7 and a["blas_built"] == 0 and a["blas_loaded"] == 0
    live = client.app.state.live.get(scene)
    inst = live.instance_of_node[uid(2)]
    # 50 mm in metres, mesh scaled mm -> m
    np.testing.assert_allclose(live.tracer.instance_transform(inst)[:3, 3], [0.05, 0, 0])
    np.testing.assert_allclose(live.tracer.instance_transform(inst)[:3, :3], np.eye(3) * 1e-3)
    np.testing.assert_allclose(live.node_world[uid(2)][:3, 3], [0.05, 0, 0])


def test_moving_an_assembly_moves_its_children(client, scene, meshes) -> None:
    doc = car(meshes)
    push(client, scene, doc)
    doc["base_revision"] = 1
    doc["nodes"][3]["transform"] = translation(0, 0, 200)
    a = push(client, scene, doc)
    assert a["moved"] == [uid(3)] + [uid(10 + k) for k in range(4)]
    assert a["unchanged"] == 3


def test_geometry_change_rename_and_removal(client, scene, meshes) -> None:
    doc = car(meshes)
    push(client, scene, doc)
    doc["base_revision"] = 1
    doc["nodes"][2]["geometry"] = meshes["other"][0]
    doc["nodes"][1]["name"] = "shell"
    del doc["nodes"][7]
    a = push(client, scene, doc)
    assert a["geometry_changed"] == [uid(2)] and a["renamed"] == [uid(1)] and a["removed"] == [uid(13)]
    assert a["blas_built"] + a["blas_loaded"] == 1 and a["instances"] == 5
    nodes = {n["uuid"]: n for n in client.get(f"/scenes/{scene}/nodes").json()}
    assert nodes[uid(1)]["name"] == "shell" and uid(13) not in nodes


def test_reverting_to_known_geometry_reuses_its_bottom_level(client, scene, meshes) -> None:
    doc = car(meshes)
    push(client, scene, doc)
    doc["base_revision"] = 1
    doc["nodes"][2]["geometry"] = meshes["wheel"][0]  # the wheel mesh is in the scene already
    a = push(client, scene, doc)
    assert a["geometry_changed"] == [uid(2)] and a["blas_built"] == 0 and a["blas_reused"] == 1


def test_stale_base_revision_is_409_and_changes_nothing(client, scene, meshes) -> None:
    push(client, scene, car(meshes))
    push(client, scene, car(meshes, base_revision=1, door_x=10.0))
    before = client.get(f"/scenes/{scene}/nodes").json()
    r = client.put(f"/scenes/{scene}/document", json=car(meshes, base_revision=1, door_x=99.0))
    assert r.status_code == 409 and r.headers["content-type"] == PROBLEM
    assert r.json()["current_revision"] == 2
    assert client.get(f"/scenes/{scene}/nodes").json() == before


def test_revision_history(client, scene, meshes) -> None:
    push(client, scene, car(meshes))
    push(client, scene, car(meshes, base_revision=1))  # a no-op: no revision
    push(client, scene, car(meshes, base_revision=1, door_x=4.0))
    history = client.get(f"/scenes/{scene}/revisions").json()
    assert [h["revision"] for h in history] == [1, 2]
    assert history[0]["added"] == 8 and history[1]["moved"] == 1 and "tlas" in history[1]["seconds"]
    assert client.get(f"/scenes/{UNKNOWN_ID}/revisions").status_code == 404


def test_push_without_base_revision_is_unconditional(client, scene, meshes) -> None:
    push(client, scene, car(meshes))
    a = push(client, scene, car(meshes, base_revision=None, door_x=5.0))
    assert a["revision"] == 2 and a["moved"] == [uid(2)]


def test_unit_change_moves_everything_off_the_origin(client, scene, meshes) -> None:
    push(client, scene, car(meshes))
    a = push(client, scene, car(meshes, base_revision=1, unit="cm"))
    # the wheels and the axle sit off the origin; car, body and door have identity worlds but scaled meshes
    assert set(a["moved"]) == {uid(3)} | {uid(10 + k) for k in range(4)}
    live = client.app.state.live.get(scene)
    np.testing.assert_allclose(live.tracer.instance_transform(live.instance_of_node[uid(1)])[:3, :3],
                               np.eye(3) * 1e-2)


# ---------------------------------------------------------------- assignments


def test_materials_are_inherited_and_counted(client, scene, meshes) -> None:
    push(client, scene, car(meshes))
    r = client.put(f"/scenes/{scene}/materials/{uid(3)}", json={"type": "mirror", "reflectance": 0.9})
    assert r.status_code == 200
    client.put(f"/scenes/{scene}/materials/{uid(11)}", json={"type": "black"})
    live = client.app.state.live.get(scene)
    wheels = [live.instance_of_node[uid(10 + k)] for k in range(4)]
    assert [live.materials[i]["type"] for i in wheels] == ["mirror", "black", "mirror", "mirror"]
    assert live.instance_of_node[uid(1)] not in live.materials  # body: the default
    s = client.get(f"/scenes/{scene}").json()
    assert s["default_material_instances"] == 2 and s["materials_assigned"] == 2
    assert s["default_material"] == {"type": "lambertian", "reflectance": 0.5}
    assert "specular" in s["effects"] and "lambertian" in s["effects"]


def test_attached_light_and_sensor_move_with_their_node(client, scene, meshes) -> None:
    push(client, scene, car(meshes))
    light = client.post(f"/scenes/{scene}/lights", json={"type": "spot", "position": [0, 0, 0.5],
                                                         "direction": [1, 0, 0], "cone_deg": 30,
                                                         "intensity_cd": 500, "attached_to": uid(2)})
    assert light.status_code == 201
    sensor = client.post(f"/scenes/{scene}/sensors", json={"type": "grid", "origin": [0, 0, 0], "u": [1, 0, 0],
                                                           "v": [0, 1, 0], "nu": 4, "nv": 2, "attached_to": uid(2)})
    assert sensor.status_code == 201
    world = client.post(f"/scenes/{scene}/lights", json={"type": "point", "position": [1, 2, 3], "flux_lm": 1000})
    assert world.status_code == 201
    beam = client.post(f"/scenes/{scene}/lights", json={"type": "collimated", "origin": [0, 0, 0],
                                                        "direction": [0, 0, -1], "width": 0.1, "height": 0.2,
                                                        "up": [1, 0, 0], "illuminance_lx": 100,
                                                        "attached_to": uid(2)})
    assert beam.status_code == 201, beam.text
    ies = (Path(__file__).resolve().parents[1] / "fixtures" / "photometry" / "rab_boa2_5.ies").read_text()
    gonio = client.post(f"/scenes/{scene}/lights", json={"type": "goniometric", "position": [0, 0, 0.5],
                                                         "format": "ies", "data": ies, "direction": [0, 0, -1],
                                                         "c0": [1, 0, 0], "attached_to": uid(2)})
    assert gonio.status_code == 201, gonio.text
    doc = car(meshes, base_revision=1, door_x=250.0)
    doc["nodes"][2]["transform"] = [0.0, -1, 0, 250, 1, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]  # door swung 90° about z
    push(client, scene, doc)
    live = client.app.state.live.get(scene)
    spot = next(x for x in live.lights if x["id"] == light.json()["id"])
    np.testing.assert_allclose(spot["position"], [0.25, 0, 0.5], atol=1e-12)
    np.testing.assert_allclose(spot["direction"], [0, 1, 0], atol=1e-12)
    assert "attached_to" not in spot
    grid = live.sensors[0]
    np.testing.assert_allclose(grid["origin"], [0.25, 0, 0], atol=1e-12)
    np.testing.assert_allclose(grid["u"], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(grid["v"], [-1, 0, 0], atol=1e-12)
    fixed = next(x for x in live.lights if x["id"] == world.json()["id"])
    assert fixed["position"] == [1.0, 2.0, 3.0]
    rect = next(x for x in live.lights if x["id"] == beam.json()["id"])
    np.testing.assert_allclose(rect["up"], [0, 1, 0], atol=1e-12)  # turned with the door
    np.testing.assert_allclose(rect["direction"], [0, 0, -1], atol=1e-12)
    lamp = next(x for x in live.lights if x["id"] == gonio.json()["id"])
    np.testing.assert_allclose(lamp["c0"], [0, 1, 0], atol=1e-12)  # its C = 0 plane turned with the door
    np.testing.assert_allclose(lamp["direction"], [0, 0, -1], atol=1e-12)
    from tracer.optics.lights import pack_lights  # the transport accepts the resolved bodies as they are

    pack_lights([{k: v for k, v in x.items() if k != "instances"} for x in live.lights if x["type"] != "area"],
                live.tracer, frozenset())


def test_area_light_names_the_instances_of_its_subtree(client, scene, meshes) -> None:
    push(client, scene, car(meshes))
    r = client.post(f"/scenes/{scene}/lights", json={"type": "area", "node": uid(3), "exitance_lm_m2": 5000})
    assert r.status_code == 201
    live = client.app.state.live.get(scene)
    assert sorted(live.lights[0]["instances"]) == sorted(live.instance_of_node[uid(10 + k)] for k in range(4))


def test_area_light_facing_one_way_is_kept_and_one_facing_nothing_is_refused(client, scene, meshes) -> None:
    """`facing` (each part's own frame) reaches the tracer as given, not turned by the node; a direction no triangle
    of the subtree faces is a 422 naming `facing`, nothing stored."""
    push(client, scene, car(meshes))
    r = client.post(f"/scenes/{scene}/lights", json={"type": "area", "node": uid(3), "exitance_lm_m2": 5000,
                                                     "facing": [0, 0, 1]})
    assert r.status_code == 201, r.text
    live = client.app.state.live.get(scene)
    assert live.lights[0]["facing"] == [0, 0, 1]
    for facing, words in (([0, 0, 0], "'facing' must be 3 finite numbers"), ([1, 1, 1], "no triangle")):
        r = client.post(f"/scenes/{scene}/lights", json={"type": "area", "node": uid(3), "exitance_lm_m2": 5000,
                                                         "facing": facing})
        assert r.status_code == 422 and words in r.text, r.text
    assert len(client.get(f"/scenes/{scene}/lights").json()) == 1


def test_orphans_are_listed_restored_and_purged(client, scene, meshes) -> None:
    doc = car(meshes)
    push(client, scene, doc)
    client.put(f"/scenes/{scene}/materials/{uid(2)}", json={"type": "lambertian", "reflectance": 0.2})
    lid = client.post(f"/scenes/{scene}/lights", json={"type": "point", "position": [0, 0, 0], "intensity_cd": 1,
                                                       "attached_to": uid(2)}).json()["id"]
    without = dict(doc, base_revision=1, nodes=[n for n in doc["nodes"] if n["uuid"] != uid(2)])
    a = push(client, scene, without)
    assert a["removed"] == [uid(2)]
    assert {(o["kind"], o["id"]) for o in a["orphaned"]} == {("material", uid(2)), ("light", lid)}
    s = client.get(f"/scenes/{scene}").json()
    assert len(s["orphaned"]) == 2 and s["lights"] == 0
    assert client.get(f"/scenes/{scene}/lights/{lid}").json()["orphaned"] is True
    # the uuid comes back: both assignments live again
    a = push(client, scene, dict(doc, base_revision=2))
    assert {(o["kind"], o["id"]) for o in a["restored"]} == {("material", uid(2)), ("light", lid)}
    live = client.app.state.live.get(scene)
    assert live.materials[live.instance_of_node[uid(2)]]["reflectance"] == 0.2 and len(live.lights) == 1
    # removed again, then purged: gone for good
    push(client, scene, dict(without, base_revision=3))
    r = client.delete(f"/scenes/{scene}/orphans")
    assert len(r.json()) == 2
    assert client.get(f"/scenes/{scene}").json()["orphaned"] == []
    a = push(client, scene, dict(doc, base_revision=4))
    assert a["restored"] == [] and client.get(f"/scenes/{scene}/lights").json() == []


def test_sim_owned_objects_survive_pushes_and_follow_their_node(client, scene, meshes) -> None:
    doc = car(meshes)
    push(client, scene, doc)
    gid = meshes["other"][0]
    free = client.post(f"/scenes/{scene}/objects", json={"geometry": gid, "transform": translation(0, 0, 3),
                                                         "material": {"type": "mirror", "reflectance": 0.5}})
    assert free.status_code == 201, free.text
    held = client.post(f"/scenes/{scene}/objects", json={"geometry": gid, "attached_to": uid(3),
                                                         "transform": translation(1, 0, 0)})
    assert held.status_code == 201
    fid, hid = free.json()["id"], held.json()["id"]
    live = client.app.state.live.get(scene)
    assert live.materials[live.instance_of_node[fid]]["type"] == "mirror"
    # axle at z = 100 mm; the object 1 m along the axle's x
    np.testing.assert_allclose(live.tracer.instance_transform(live.instance_of_node[hid])[:3, 3], [1, 0, 0.1])
    doc2 = dict(doc, base_revision=1, nodes=[dict(n) for n in doc["nodes"]])
    doc2["nodes"][3]["transform"] = translation(0, 0, 500)
    push(client, scene, doc2)
    live = client.app.state.live.get(scene)
    np.testing.assert_allclose(live.tracer.instance_transform(live.instance_of_node[hid])[:3, 3], [1, 0, 0.5])
    np.testing.assert_allclose(live.tracer.instance_transform(live.instance_of_node[fid])[:3, 3], [0, 0, 3])
    # an empty document removes every node; the free object stays, the attached one is orphaned
    a = push(client, scene, {"base_revision": 2, "length_unit": "mm", "nodes": []})
    assert len(a["removed"]) == 8 and a["instances"] == 1
    assert {o["id"] for o in a["orphaned"]} == {hid}
    live = client.app.state.live.get(scene)
    assert set(live.instance_of_node) == {fid}
    assert client.delete(f"/scenes/{scene}/objects/{fid}").status_code == 204
    assert client.app.state.live.get(scene).instance_of_node == {}


def test_material_on_an_object_and_deletion(client, scene, meshes) -> None:
    push(client, scene, car(meshes))
    oid = client.post(f"/scenes/{scene}/objects", json={"geometry": meshes["other"][0]}).json()["id"]
    assert client.put(f"/scenes/{scene}/materials/{oid}", json={"type": "black"}).status_code == 200
    assert client.delete(f"/scenes/{scene}/materials/{oid}").status_code == 204
    assert client.delete(f"/scenes/{scene}/materials/{oid}").status_code == 404


def test_live_registry_contract(client, scene, meshes) -> None:
    push(client, scene, car(meshes))
    live = client.app.state.live.get(scene)
    assert live.scene_id == scene and live.revision == 1
    assert set(live.node_world) == {n["uuid"] for n in car(meshes)["nodes"]}
    assert set(live.instance_of_node) == {uid(1), uid(2)} | {uid(10 + k) for k in range(4)}
    assert sorted(live.tracer.instances()) == sorted(live.instance_of_node.values())
    from service.errors import NotFound

    with pytest.raises(NotFound):
        client.app.state.live.get("no-such-scene")
    seen = []
    client.app.state.live.subscribe(lambda sid, rev: seen.append((sid, rev)))
    push(client, scene, car(meshes, base_revision=1, door_x=1.0))
    assert seen == [(scene, 2)]


def test_colors_round_trip(client, scene, meshes) -> None:
    doc = car(meshes)
    doc["nodes"][1]["color"] = [0.8, 0.1, 0.1]
    push(client, scene, doc)
    doc = dict(doc, base_revision=1, nodes=[dict(n) for n in doc["nodes"]])
    doc["nodes"][1]["color"] = [0.1, 0.8, 0.1]
    a = push(client, scene, doc)
    assert a["recolored"] == [uid(1)] and a["moved"] == []
    nodes = {n["uuid"]: n for n in client.get(f"/scenes/{scene}/nodes").json()}
    assert nodes[uid(1)]["color"] == [0.1, 0.8, 0.1]


def test_nodes_without_parent_field_and_deep_trees(client, scene, meshes) -> None:
    nodes = [node(uid(100), None, "r")]
    nodes += [node(uid(101 + k), uid(100 + k), f"n{k}", translation(1, 0, 0)) for k in range(50)]
    nodes[-1]["geometry"] = meshes["body"][0]
    a = push(client, scene, {"base_revision": 0, "length_unit": "m", "nodes": nodes})
    assert len(a["added"]) == 51
    live = client.app.state.live.get(scene)
    np.testing.assert_allclose(live.node_world[uid(150)][:3, 3], [50, 0, 0])


def test_byte_identical_node_list_is_recognised_and_still_checked(client, scene, meshes) -> None:
    """A re-push whose node bytes equal the last accepted ones skips decoding them — but not the header checks."""
    import json

    doc = car(meshes)
    raw = lambda d: json.dumps(d).encode()  # noqa: E731
    hdr = {"content-type": "application/json"}
    assert client.put(f"/scenes/{scene}/document", content=raw(doc), headers=hdr).status_code == 200
    again = client.put(f"/scenes/{scene}/document", content=raw(dict(doc, base_revision=1)), headers=hdr)
    assert again.status_code == 200 and again.json()["unchanged"] == 8 and again.json()["revision"] == 1
    # same node bytes, but a header the schema refuses: still refused
    bad = client.put(f"/scenes/{scene}/document", content=raw(dict(doc, base_revision=1, author="x")), headers=hdr)
    assert bad.status_code == 422
    # same node bytes, another unit: everything rescales (not a no-op)
    moved = client.put(f"/scenes/{scene}/document", content=raw(dict(doc, base_revision=1, length_unit="cm")),
                       headers=hdr)
    assert moved.status_code == 200 and moved.json()["revision"] == 2 and moved.json()["moved"]
    # and a real change right after is seen
    doc2 = car(meshes, base_revision=2, door_x=3.0, unit="cm")
    a = client.put(f"/scenes/{scene}/document", content=raw(doc2), headers=hdr).json()
    assert a["moved"] == [uid(2)] and a["revision"] == 3


def test_a_long_sequence_of_edits_stays_consistent(client, scene, meshes, rng) -> None:
    """Thirty pushes of random edits (moves, renames, geometry swaps, insertions, removals anywhere): each
    answer equals the diff of fully decoded trees, and the stored tree equals the pushed one."""
    import json

    from service.document import decode_document
    from service.tree import Tree, diff_trees

    gids = [meshes[k][0] for k in ("body", "wheel", "other")]
    nodes = [node(uid(500), None, "root")]
    nodes += [node(uid(501 + k), uid(500), f"p{k}", translation(k, 0, 0), geometry=gids[k % 3]) for k in range(300)]
    revision, fresh = 0, 1000
    previous = None
    for step in range(30):
        if step:
            for _ in range(int(rng.integers(1, 4))):
                k = int(rng.integers(1, len(nodes)))
                what = int(rng.integers(0, 5))
                n = nodes[k] = dict(nodes[k])
                if what == 0:
                    n["transform"] = translation(float(rng.normal()), 0, 0)
                elif what == 1:
                    n["name"] = f"renamed{step}"
                elif what == 2:
                    n["geometry"] = gids[int(rng.integers(0, 3))]
                elif what == 3:
                    nodes.insert(k, node(uid(fresh), uid(500), f"new{fresh}", geometry=gids[0]))
                    fresh += 1
                else:
                    del nodes[k]
        body = json.dumps({"base_revision": revision, "length_unit": "mm", "nodes": nodes}).encode()
        r = client.put(f"/scenes/{scene}/document", content=body, headers={"content-type": "application/json"})
        assert r.status_code == 200, r.text
        answer = r.json()
        current = Tree.build(*decode_document(body, set(), set(gids)).columns(), "mm")
        if previous is not None:
            expect = diff_trees(previous, current).summary()
            assert {k: answer[k] for k in expect} == expect
        previous, revision = current, answer["revision"]
        stored = {n["uuid"]: (n["parent"], n["name"], n["transform"], n["geometry"])
                  for n in client.get(f"/scenes/{scene}/nodes").json()}
        assert stored == {n["uuid"]: (n["parent"], n["name"], [float(x) for x in n["transform"]], n["geometry"])
                          for n in nodes}
    live = client.app.state.live.get(scene)
    assert len(live.instance_of_node) == sum(1 for n in nodes if n["geometry"])


@pytest.mark.parametrize("materials", [
    {},
    {3: {"type": "mirror", "reflectance": 0.9}},
    {1: {"type": "mix", "diffuse": 0.5, "specular": 0.0}},
    {1: {"type": "dielectric", "ior": 1.5, "absorption_per_m": 2.0}, 11: {"type": "black"}},
    {0: {"type": "dielectric", "ior": 1.3, "scattering_per_m": 1.0}},
])
def test_summary_effects_agree_with_the_transport(client, scene, meshes, materials) -> None:
    from tracer.simulate import Simulation

    push(client, scene, car(meshes))
    for k, body in materials.items():
        assert client.put(f"/scenes/{scene}/materials/{uid(k)}", json=body).status_code == 200
    live = client.app.state.live.get(scene)
    lights = [{"type": "point", "position": [0, 0, 5], "intensity_cd": 1.0}]
    sim = Simulation(live.tracer, live.materials, lights, default_material=live.default_material)
    assert client.get(f"/scenes/{scene}").json()["effects"] == sim.effects


def test_scene_effects_follow_the_tracer_and_skip_bodies_it_now_refuses() -> None:
    """A material stored under older, looser rules (σs above today's bound) must not make a summary fail."""
    from types import SimpleNamespace

    from service.state import scene_effects

    live = SimpleNamespace(materials={0: {"type": "mirror", "reflectance": 0.9},
                                      1: {"type": "dielectric", "ior": 1.5, "scattering_per_m": 1e12}},
                           default_material={"type": "dielectric", "ior": 1.5, "absorption_per_m": 2.0},
                           lights=[{"type": "point", "position": [0, 0, 1], "flux_lm": 1.0}])
    assert scene_effects(live) == ["lambertian", "specular", "fresnel", "absorption", "polarization"]
    assert scene_effects(live, uses_default=False) == ["lambertian", "specular"]
    live.lights[0]["polarization"] = {"type": "linear", "axis": [1, 0, 0]}
    assert scene_effects(live, uses_default=False) == ["lambertian", "specular", "polarization"]
