"""The [k] ranks of same-named siblings survive a restart (issue 42): ``nodes.position`` follows the pushed order,
after a push that only reorders (no new revision) and after removals followed by appends (no tied positions)."""

from __future__ import annotations

from service_helpers import make_client, node, translation, uid
from test_identity_api import assembly, put, upload


def paths(client, scene: str) -> dict[str, str]:
    return {n["uuid"]: n["path"] for n in client.get(f"/scenes/{scene}/nodes").json()}


def test_a_reorder_of_same_named_siblings_survives_a_restart(tmp_path) -> None:
    from service_helpers import glb, grid_mesh

    meshes = {"body": glb(*grid_mesh(2)), "wheel": glb(*grid_mesh(3, z=1.0))}
    with make_client(tmp_path) as client:
        upload(client, meshes)
        scene = client.post("/scenes", json={"name": "asm"}).json()["id"]
        doc = assembly(meshes)
        put(client, scene, doc)
        assert paths(client, scene)[uid(2)] == "asm/plate∕top/bolt"
        order = [n["uuid"] for n in doc["nodes"]]
        i2, i3 = order.index(uid(2)), order.index(uid(3))
        doc["nodes"][i2], doc["nodes"][i3] = doc["nodes"][i3], doc["nodes"][i2]
        doc["base_revision"] = 1
        a = put(client, scene, doc)  # the same tree in another order: no change, no new revision
        assert a["revision"] == 1 and a["unchanged"] == len(doc["nodes"])
        before = paths(client, scene)
        assert before[uid(3)] == "asm/plate∕top/bolt" and before[uid(2)] == "asm/plate∕top/bolt[2]"
        # remove the first bolt, then append a new one: its row number must not tie with an older row's position
        doc["nodes"] = [n for n in doc["nodes"] if n["uuid"] != uid(3)]
        put(client, scene, doc)
        doc["nodes"].append(node(uid(9), uid(1), "bolt", translation(40, 0, 0), geometry=meshes["wheel"][0]))
        doc["base_revision"] = 2
        put(client, scene, doc)
        before = paths(client, scene)
        assert before[uid(9)] == "asm/plate∕top/bolt[3]"
    with make_client(tmp_path) as client:  # a restart: the tree is read back from the database
        assert paths(client, scene) == before
