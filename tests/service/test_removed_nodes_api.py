"""The scene remembers removed nodes (issue 42): ``GET /scenes/{id}/removed-nodes``, ``restored_nodes`` in the
push answer and its dry run, forgetting after ``removed_keep_revisions`` revisions or ``removed_keep_days`` days,
and the memory surviving a restart."""

from __future__ import annotations

import datetime

import pytest
from service_helpers import make_client, uid
from test_identity_api import assembly, identity, put, upload


@pytest.fixture(scope="module")
def meshes():
    from service_helpers import glb, grid_mesh

    return {"body": glb(*grid_mesh(2)), "wheel": glb(*grid_mesh(3, z=1.0))}


def without_bolt(meshes, base_revision: int) -> dict:
    doc = assembly(meshes, base_revision=base_revision, identity=identity(**{uid(4): None}))
    doc["nodes"] = [n for n in doc["nodes"] if n["uuid"] != uid(4)]
    return doc


def test_a_removed_node_is_remembered_and_comes_back_with_its_assignments(tmp_path, meshes) -> None:
    with make_client(tmp_path) as client:
        upload(client, meshes)
        scene = client.post("/scenes", json={"name": "asm"}).json()["id"]
        put(client, scene, assembly(meshes, identity=identity()))
        mirror = {"type": "mirror", "reflectance": 0.9}
        assert client.put(f"/scenes/{scene}/materials/{uid(4)}", json=mirror).status_code == 200
        assert client.get(f"/scenes/{scene}/removed-nodes").json() == []
        a = put(client, scene, without_bolt(meshes, 1))
        assert a["removed"] == [uid(4)] and a["restored_nodes"] == []
        gone = client.get(f"/scenes/{scene}/removed-nodes").json()
        assert [g["uuid"] for g in gone] == [uid(4)]
        g = gone[0]
        assert g["path"] == "asm/plate∕top/bolt[3]" and g["product"] == "M3 bolt" and g["removed_revision"] == 2
        assert g["signature"]["volume"] == 12.5 and g["length_unit"] == "mm" and g["parent"] == uid(1)
        assert g["assignments"] == [{"kind": "material", "id": uid(4)}]
        assert g["transform"][3] == 30.0 and g["world"][3] != g["transform"][3]  # in the parent, and from the root
        datetime.datetime.fromisoformat(g["removed_at"])
    with make_client(tmp_path) as client:  # a restart: the memory is in the database
        assert client.get(f"/scenes/{scene}/removed-nodes").json() == gone
        back = assembly(meshes, base_revision=2, identity=identity())
        d = put(client, scene, back, dry_run=True)
        assert d["restored_nodes"] == [uid(4)] and d["added"] == [uid(4)]
        assert d["restored"] == [{"kind": "material", "id": uid(4), "node": uid(4)}]
        assert client.get(f"/scenes/{scene}/removed-nodes").json() == gone  # a dry run forgets nothing
        r = put(client, scene, back)
        assert r["restored_nodes"] == [uid(4)] and r["restored"] == d["restored"]
        assert client.get(f"/scenes/{scene}/removed-nodes").json() == []
        assert client.get(f"/scenes/{scene}").json()["orphaned"] == []


def test_the_memory_forgets_after_its_revisions(tmp_path, meshes) -> None:
    with make_client(tmp_path, removed_keep_revisions=2) as client:
        upload(client, meshes)
        scene = client.post("/scenes", json={"name": "asm"}).json()["id"]
        put(client, scene, assembly(meshes, identity=identity()))
        assert client.put(f"/scenes/{scene}/materials/{uid(4)}", json={"type": "black"}).status_code == 200
        put(client, scene, without_bolt(meshes, 1))  # revision 2 removes the bolt
        moved = without_bolt(meshes, 2)
        moved["nodes"][0]["transform"][3] = 5.0
        put(client, scene, moved)  # revision 3: one revision later, still remembered
        assert len(client.get(f"/scenes/{scene}/removed-nodes").json()) == 1
        moved["base_revision"] = 3
        moved["nodes"][0]["transform"][3] = 6.0
        put(client, scene, moved)  # revision 4: two revisions later, forgotten
        assert client.get(f"/scenes/{scene}/removed-nodes").json() == []
        # the assignment itself is kept (orphaned) until purged: the UUID pushed again still restores it
        assert client.get(f"/scenes/{scene}").json()["orphaned"][0]["node"] == uid(4)


def test_the_memory_forgets_after_its_days_and_can_be_off(tmp_path, meshes) -> None:
    with make_client(tmp_path, removed_keep_days=0.0) as client:
        upload(client, meshes)
        scene = client.post("/scenes", json={"name": "asm"}).json()["id"]
        put(client, scene, assembly(meshes, identity=identity()))
        put(client, scene, without_bolt(meshes, 1))
        assert client.get(f"/scenes/{scene}/removed-nodes").json() == []
    with make_client(tmp_path / "b", removed_keep_days=1.0) as client:
        upload(client, meshes)
        scene = client.post("/scenes", json={"name": "asm"}).json()["id"]
        put(client, scene, assembly(meshes, identity=identity()))
        put(client, scene, without_bolt(meshes, 1))
        state = client.app.state.manager.scenes.state(scene)
        old = datetime.datetime.now(datetime.UTC) - datetime.timedelta(days=2)
        state.removed[uid(4)]["removed_at"] = old.isoformat()  # as if pushed two days ago
        moved = without_bolt(meshes, 2)
        moved["nodes"][0]["transform"][3] = 5.0
        put(client, scene, moved)
        assert client.get(f"/scenes/{scene}/removed-nodes").json() == []


def test_bad_memory_settings_are_refused() -> None:
    from pydantic import ValidationError

    from service.config import Settings

    with pytest.raises(ValidationError, match="removed_keep_revisions"):
        Settings(removed_keep_revisions=-1)
    with pytest.raises(ValidationError, match="removed_keep_days"):
        Settings(removed_keep_days=float("nan"))


def test_removed_nodes_of_an_unknown_scene_is_404(tmp_path) -> None:
    with make_client(tmp_path) as client:
        r = client.get("/scenes/00000000-0000-4000-8000-000000000000/removed-nodes")
        assert r.status_code == 404
