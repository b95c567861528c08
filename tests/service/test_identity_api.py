"""Identity records, the reconciliation report and dry runs (issue 17, the service side).

The CAD adapter reconciles a new document against the tree the scene holds, so the service keeps
what matching needs per node (product name, shape signature), serves it back with each node's path
and world transform, echoes the adapter's reconciliation report, and answers a dry run that changes
nothing. Every refused request leaves the stored state exactly as it was.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import sqlalchemy as sa
from service_helpers import UNKNOWN_ID, car_document, glb, grid_mesh, make_client, node, translation, uid

PROBLEM = "application/problem+json"
HDR = {"content-type": "application/json"}
DIFF_KEYS = ("added", "removed", "moved", "geometry_changed", "renamed", "reparented", "recolored", "unchanged",
             "orphaned", "restored")


@pytest.fixture(scope="module")
def meshes() -> dict[str, tuple[str, bytes]]:
    return {"body": glb(*grid_mesh(2)), "wheel": glb(*grid_mesh(3, z=1.0)), "other": glb(*grid_mesh(4, z=2.0))}


def upload(client, meshes, names=("body", "wheel")) -> None:
    for name in names:
        gid, data = meshes[name]
        assert client.put(f"/geometries/{gid}", content=data).status_code in (200, 201)


@pytest.fixture
def client(tmp_path, meshes):
    with make_client(tmp_path) as c:
        upload(c, meshes)  # "other" is not uploaded
        yield c


@pytest.fixture
def scene(client) -> str:
    return client.post("/scenes", json={"name": "asm"}).json()["id"]


def raw(doc: dict) -> bytes:
    """The body as the adapter writes it: header members (identity, reconciliation) before ``nodes``."""
    head = {k: v for k, v in doc.items() if k != "nodes"}
    return json.dumps({**head, "nodes": doc["nodes"]}).encode()


def put(client, scene: str, doc: dict | bytes, status: int = 200, dry_run: bool = False) -> dict:
    body = doc if isinstance(doc, bytes) else raw(doc)
    url = f"/scenes/{scene}/document" + ("?dry_run=true" if dry_run else "")
    r = client.put(url, content=body, headers=HDR)
    assert r.status_code == status, r.text
    if status >= 400:
        assert r.headers["content-type"] == PROBLEM
    return r.json()


def rot_z(deg: float, t: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> list[float]:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return [c, -s, 0.0, t[0], s, c, 0.0, t[1], 0.0, 0.0, 1.0, t[2], 0.0, 0.0, 0.0, 1.0]


def signature(volume: float = 12.5, **kw: Any) -> dict[str, Any]:
    out = {"volume": volume, "area": 40.0, "moments": [1.0, 2.0, 2.5], "centroid": [0.5, -1.0, 3.0],
           "axes": [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]}
    out.update(kw)
    return out


def assembly(meshes, base_revision: int | None = 0, bolt_x: float = 10.0, **head: Any) -> dict[str, Any]:
    """Two roots named "asm"; the first holds a plate named "plate/top" (a slash in the name) with three
    bolts of one name and a washer; units mm."""
    body, wheel = meshes["body"][0], meshes["wheel"][0]
    nodes = [node(uid(0), None, "asm", translation(1, 0, 0)),
             node(uid(1), uid(0), "plate/top", rot_z(90, (0, 2, 0))),
             node(uid(2), uid(1), "bolt", translation(bolt_x, 0, 0), geometry=wheel),
             node(uid(5), uid(1), "washer", translation(0, 0, 3), geometry=body),
             node(uid(3), uid(1), "bolt", translation(20, 0, 0), geometry=wheel),
             node(uid(4), uid(1), "bolt", rot_z(30, (30, 0, 1)), geometry=wheel),
             node(uid(6), None, "asm", translation(0, 0, -5))]
    doc: dict[str, Any] = {"base_revision": base_revision, "length_unit": "mm", "source": {"name": "asm.step"}}
    doc.update(head)
    doc["nodes"] = nodes
    return doc


def identity(**over: Any) -> dict[str, Any]:
    out: dict[str, Any] = {uid(1): {"product": "PLATE-100", "signature": signature(100.0)},
                           uid(2): {"product": "M3 bolt", "signature": signature()},
                           uid(3): {"product": "M3 bolt", "signature": signature()},
                           uid(4): {"product": "M3 bolt", "signature": signature()},
                           uid(5): {"product": "nodes", "signature": None}}  # a product named like the member
    out.update(over)
    return {k: v for k, v in out.items() if v is not None}


def nodes_of(client, scene: str) -> dict[str, dict]:
    return {n["uuid"]: n for n in client.get(f"/scenes/{scene}/nodes").json()}


def snapshot(client, scene: str) -> dict[str, Any]:
    live = client.app.state.live.get(scene)
    return {"summary": client.get(f"/scenes/{scene}").json(), "nodes": client.get(f"/scenes/{scene}/nodes").json(),
            "revisions": client.get(f"/scenes/{scene}/revisions").json(),
            "materials": client.get(f"/scenes/{scene}/materials").json(),
            "instances": sorted((i, live.tracer.instance_geometry(i), live.tracer.instance_transform(i).tolist())
                                for i in live.tracer.instances())}


class Writes:
    """Counts the rows written to ``node_identity`` (inserted or deleted statements) on an engine."""

    def __init__(self, engine) -> None:
        self.rows = 0
        self.statements = 0
        sa.event.listen(engine, "before_cursor_execute", self._seen)

    def _seen(self, conn, cursor, statement: str, parameters, context, executemany: bool) -> None:
        if "node_identity" in statement and not statement.lstrip().upper().startswith("SELECT"):
            self.statements += 1
            self.rows += len(parameters) if executemany else 1


# ---------------------------------------------------------------- stored and served


def test_identity_is_stored_and_served_with_paths_and_worlds(client, scene, meshes) -> None:
    a = put(client, scene, assembly(meshes, identity=identity()))
    assert a["revision"] == 1 and len(a["added"]) == 7 and a["dry_run"] is False and a["reconciliation"] is None
    nodes = nodes_of(client, scene)
    assert {u: n["path"] for u, n in nodes.items()} == {
        uid(0): "asm", uid(1): "asm/plate\u2215top", uid(2): "asm/plate\u2215top/bolt",
        uid(5): "asm/plate\u2215top/washer", uid(3): "asm/plate\u2215top/bolt[2]",
        uid(4): "asm/plate\u2215top/bolt[3]", uid(6): "asm[2]"}
    # world = root_from_node, the product of the locals from the root, in the document's unit (mm)
    doc = assembly(meshes)
    local = {n["uuid"]: np.array(n["transform"], dtype=float).reshape(4, 4) for n in doc["nodes"]}
    parent = {n["uuid"]: n["parent"] for n in doc["nodes"]}
    for u, n in nodes.items():
        w, p = local[u], parent[u]
        while p is not None:
            w, p = local[p] @ w, parent[p]
        np.testing.assert_allclose(np.array(n["world"]).reshape(4, 4), w, rtol=0, atol=1e-12)
        assert n["transform"] == [float(x) for x in local[u].ravel()]  # the existing fields are kept
    np.testing.assert_allclose(nodes[uid(2)]["world"][3::4], [1, 12, 0, 1], atol=1e-12)  # mm, not metres
    assert nodes[uid(2)]["product"] == "M3 bolt" and nodes[uid(2)]["signature"] == signature()
    assert nodes[uid(1)]["signature"] == signature(100.0)
    assert nodes[uid(5)]["product"] == "nodes" and nodes[uid(5)]["signature"] is None
    assert nodes[uid(0)]["product"] is None and nodes[uid(0)]["signature"] is None  # no entry, no record
    assert nodes[uid(2)]["instance"] is not None and nodes[uid(0)]["instance"] is None


def test_identity_survives_a_restart_and_an_unchanged_push_writes_nothing(tmp_path, meshes) -> None:
    with make_client(tmp_path) as c:
        upload(c, meshes)
        sid = c.post("/scenes", json={"name": "asm"}).json()["id"]
        put(c, sid, assembly(meshes, identity=identity()))
        before = c.get(f"/scenes/{sid}/nodes").json()
    with make_client(tmp_path) as c:  # a new process over the same database
        assert c.get(f"/scenes/{sid}/nodes").json() == before
        writes = Writes(c.app.state.engine)
        a = put(c, sid, assembly(meshes, base_revision=1, bolt_x=11.0, identity=identity()))
        assert a["moved"] == [uid(2)] and a["revision"] == 2
        assert writes.statements == 0  # the records equal the stored ones: no identity SQL at all
        a = put(c, sid, assembly(meshes, base_revision=2, bolt_x=11.0, identity=identity()))
        assert a["revision"] == 2 and writes.statements == 0


def test_only_changed_records_are_written(client, scene, meshes) -> None:
    put(client, scene, assembly(meshes, identity=identity()))
    writes = Writes(client.app.state.engine)
    # one record changes along with a move (the incremental decode path)
    a = put(client, scene, assembly(meshes, base_revision=1, bolt_x=12.0,
                                    identity=identity(**{uid(3): {"product": "M3x8", "signature": signature(9.0)}})))
    assert a["moved"] == [uid(2)]
    assert writes.rows == 2  # its old row deleted, its new row inserted
    assert nodes_of(client, scene)[uid(3)]["product"] == "M3x8"
    # a record dropped: only its row is deleted
    writes.rows = 0
    ident = identity(**{uid(3): {"product": "M3x8", "signature": signature(9.0)}, uid(4): None})
    put(client, scene, assembly(meshes, base_revision=2, bolt_x=12.0, identity=ident))
    assert writes.rows == 1 and nodes_of(client, scene)[uid(4)]["product"] is None


def test_identity_only_change_on_byte_identical_nodes_is_stored(tmp_path, meshes) -> None:
    with make_client(tmp_path) as c:
        upload(c, meshes)
        sid = c.post("/scenes", json={"name": "asm"}).json()["id"]
        first = assembly(meshes, identity=identity())
        put(c, sid, first)
        changed = identity(**{uid(2): {"product": "M3 bolt", "signature": signature(13.0)}})
        second = assembly(meshes, base_revision=1, identity=changed)
        assert raw(first).endswith(raw(second)[raw(second).index(b'"nodes": ['):])  # the same node bytes
        notified: list[tuple[str, int]] = []
        c.app.state.live.subscribe(lambda s, r: notified.append((s, r)))
        a = put(c, sid, second)
        assert a["revision"] == 1 and a["unchanged"] == 7 and a["moved"] == [] and a["added"] == []
        assert nodes_of(c, sid)[uid(2)]["signature"]["volume"] == 13.0
        assert [h["revision"] for h in c.get(f"/scenes/{sid}/revisions").json()] == [1]  # no new revision
        assert notified == []
        # also from a stale base: the tree is the current one, so it is a no-op for the tree
        third = assembly(meshes, base_revision=0, identity=identity(**{uid(2): None}))
        assert put(c, sid, third)["revision"] == 1
        assert nodes_of(c, sid)[uid(2)]["product"] is None
        # omitting identity clears every record
        put(c, sid, assembly(meshes, base_revision=1))
        assert all(n["product"] is None and n["signature"] is None for n in nodes_of(c, sid).values())
        put(c, sid, second)
    with make_client(tmp_path) as c:
        assert nodes_of(c, sid)[uid(2)]["signature"]["volume"] == 13.0


def test_header_with_identity_parses_on_every_decode_path(meshes) -> None:
    """The fast path, the byte-identical node list and the incremental decode all read the new header
    members (a product named "nodes" in the header does not fool the search for the node list)."""
    from service.document import decode_document, decode_incremental, remember, same_nodes
    from service.schemas import DocumentPush
    from service.tree import Tree

    rec = {"matched": {"structure": 3, "signature": 4}, "ambiguous": [], "seconds": 0.01, "source": "nodes"}
    doc = assembly(meshes, identity=identity(), reconciliation=rec)
    body = raw(doc)
    known = {meshes["body"][0], meshes["wheel"][0]}
    expected = DocumentPush.model_validate_json(body).model_copy(update={"nodes": []})
    d = decode_document(body, set(), known)
    assert d.fast and d.header == expected
    tree = Tree.build(*d.columns(), "mm")
    previous = remember(body, tree.names)
    assert previous is not None
    again = raw(assembly(meshes, base_revision=1, identity=identity(), reconciliation=rec))
    header = same_nodes(again, previous)
    assert header is not None and header.identity == expected.identity and header.base_revision == 1
    moved = raw(assembly(meshes, base_revision=1, bolt_x=5.0, identity=identity(**{uid(2): None}),
                         reconciliation=rec))
    inc = decode_incremental(moved, previous, tree, known)
    assert inc is not None
    assert inc[0].header.identity is not None and uid(2) not in inc[0].header.identity
    assert inc[0].header.reconciliation == expected.reconciliation


# ---------------------------------------------------------------- refused, and nothing changes


def test_unknown_identity_key_is_422_and_changes_nothing(client, scene, meshes) -> None:
    put(client, scene, assembly(meshes, identity=identity()))
    before = snapshot(client, scene)
    stranger = uid(99)
    for bolt_x in (10.0, 77.0):  # with the tree unchanged, and with a move in the same push
        for dry_run in (False, True):
            doc = assembly(meshes, base_revision=1, bolt_x=bolt_x,
                           identity=identity(**{stranger: {"product": "ghost", "signature": None}}))
            p = put(client, scene, doc, 422, dry_run=dry_run)
            assert stranger in p["detail"] and p["errors"][0]["loc"] == ["identity", stranger]
            assert snapshot(client, scene) == before


BAD_SIGNATURES = {
    "negative volume": signature(-1.0),
    "negative area": signature(area=-0.5),
    "NaN volume": signature(float("nan")),
    "infinite centroid": signature(centroid=[0.0, float("inf"), 0.0]),
    "two moments": signature(moments=[1.0, 2.0]),
    "negative moment": signature(moments=[-1.0, 2.0, 3.0]),
    "unsorted moments": signature(moments=[3.0, 2.0, 1.0]),
    "eight axes": signature(axes=[1.0] * 8),
    "boolean volume": signature(True),
    "string area": signature(area="40"),
    "extra field": signature(density=7.8),
    "volume missing": {k: v for k, v in signature().items() if k != "volume"},
}


@pytest.mark.parametrize("name", sorted(BAD_SIGNATURES))
def test_bad_signature_is_422_and_changes_nothing(client, scene, meshes, name: str) -> None:
    put(client, scene, assembly(meshes, identity=identity()))
    before = snapshot(client, scene)
    for bolt_x in (10.0, 55.0):
        doc = assembly(meshes, base_revision=1, bolt_x=bolt_x,
                       identity=identity(**{uid(2): {"product": "M3 bolt", "signature": BAD_SIGNATURES[name]}}))
        p = put(client, scene, doc, 422)
        assert any(e["loc"][:3] == ["identity", uid(2), "signature"] for e in p["errors"]), p
        assert snapshot(client, scene) == before


@pytest.mark.parametrize("record", [{"product": "x" * 501}, {"product": 5}, {"product": "a", "colour": "red"},
                                    "M3 bolt"])
def test_bad_identity_record_is_422_and_changes_nothing(client, scene, meshes, record) -> None:
    put(client, scene, assembly(meshes, identity=identity()))
    before = snapshot(client, scene)
    put(client, scene, assembly(meshes, base_revision=1, identity=identity(**{uid(2): record})), 422)
    put(client, scene, assembly(meshes, base_revision=1, identity={"not-a-uuid": {"product": "a"}}), 422)
    assert snapshot(client, scene) == before


# ---------------------------------------------------------------- reconciliation


RECONCILIATION = {"matched": {"structure": 4, "signature": 2, "alignment": 1},
                  "ambiguous": [{"uuid": uid(3), "path": "asm/plate\u2215top/bolt[2]",
                                 "candidates": [uid(3), uid(4)], "reason": "identical parts swapped in place"}],
                  "seconds": 0.25, "source": "asm_rev2.step"}


def test_reconciliation_is_echoed(client, scene, meshes) -> None:
    a = put(client, scene, assembly(meshes, reconciliation=RECONCILIATION, identity=identity()))
    assert a["reconciliation"] == RECONCILIATION and a["dry_run"] is False
    a = put(client, scene, assembly(meshes, base_revision=1, reconciliation={"matched": {"uuid": 7}}))
    assert a["reconciliation"] == {"matched": {"uuid": 7}, "ambiguous": [], "seconds": None, "source": None}
    assert put(client, scene, assembly(meshes, base_revision=1))["reconciliation"] is None
    d = put(client, scene, assembly(meshes, base_revision=1, bolt_x=3.0, reconciliation=RECONCILIATION), dry_run=True)
    assert d["reconciliation"] == RECONCILIATION


@pytest.mark.parametrize("bad", [{"matched": {"structure": -1}}, {"matched": {"structure": 1.5}},
                                 {"matched": {"structure": True}}, {"seconds": -0.1}, {"seconds": float("nan")},
                                 {"ambiguous": [{"uuid": "x", "path": "a", "candidates": [], "reason": "r"}]},
                                 {"ambiguous": [{"uuid": uid(1), "path": "a", "candidates": ["y"], "reason": "r"}]},
                                 {"ambiguous": [{"uuid": uid(1), "path": "a", "candidates": []}]},
                                 {"matched": {}, "verdict": "ok"}])
def test_bad_reconciliation_is_422_and_changes_nothing(client, scene, meshes, bad) -> None:
    put(client, scene, assembly(meshes, identity=identity()))
    before = snapshot(client, scene)
    p = put(client, scene, assembly(meshes, base_revision=1, bolt_x=4.0, reconciliation=bad,
                                    identity=identity(**{uid(2): None})), 422)
    assert p["errors"][0]["loc"][0] == "reconciliation"
    assert snapshot(client, scene) == before


def test_openapi_documents_the_new_members(client) -> None:
    api = client.get("/openapi.json").json()
    put_ = api["paths"]["/scenes/{scene_id}/document"]["put"]
    body = put_["requestBody"]["content"]["application/json"]["schema"]
    # the models the body refers to are in the components, where its refs point
    assert {"identity", "reconciliation"} <= set(body["properties"]) and "Signature" in api["components"]["schemas"]
    assert [p["name"] for p in put_["parameters"]] == ["scene_id", "dry_run"]
    schemas = api["components"]["schemas"]
    assert {"reconciliation", "dry_run", "blas_to_build", "missing_geometries"} <= set(
        schemas["PushPublic"]["properties"])


# ---------------------------------------------------------------- dry runs


def test_dry_run_answers_the_diff_and_changes_nothing(client, scene, meshes) -> None:
    put(client, scene, assembly(meshes, identity=identity()))
    assert client.put(f"/scenes/{scene}/materials/{uid(4)}", json={"type": "black"}).is_success
    light = client.post(f"/scenes/{scene}/lights", json={"type": "point", "position": [0, 0, 1],
                                                         "intensity_cd": 1, "attached_to": uid(4)}).json()
    notified: list[tuple[str, int]] = []
    client.app.state.live.subscribe(lambda s, r: notified.append((s, r)))
    live_before = client.app.state.live.get(scene)
    before = snapshot(client, scene)
    other = meshes["other"][0]  # not uploaded yet
    doc = assembly(meshes, base_revision=1, bolt_x=15.0, identity=identity(**{uid(2): None, uid(4): None}))
    doc["nodes"] = [n for n in doc["nodes"] if n["uuid"] != uid(4)]  # bolt[2] removed (its material, its light)
    doc["nodes"][1]["name"] = "plate"  # renamed
    doc["nodes"].append(node(uid(7), uid(1), "lens", translation(0, 0, 9), geometry=other))
    doc["nodes"][3]["geometry"] = meshes["wheel"][0]  # the washer now uses the bolt's mesh (held already)
    d = put(client, scene, doc, dry_run=True)
    assert d["dry_run"] is True and d["revision"] == 1 and d["blas_built"] == 0
    assert d["added"] == [uid(7)] and d["removed"] == [uid(4)] and d["moved"] == [uid(2)]
    assert d["renamed"] == [uid(1)] and d["geometry_changed"] == [uid(5)] and d["unchanged"] == 3
    assert sorted((o["kind"], o["id"]) for o in d["orphaned"]) == [("light", light["id"]), ("material", uid(4))]
    assert d["restored"] == []
    assert d["missing_geometries"] == [other] and d["blas_to_build"] == [other] and d["blas_reused"] == 1
    assert d["instances"] == 4
    assert set(d["seconds"]) >= {"validate", "diff", "total"}
    # nothing changed: not the stored scene, not the tree in memory, not the live view
    assert snapshot(client, scene) == before
    assert client.app.state.live.get(scene) is live_before and notified == []
    assert nodes_of(client, scene)[uid(2)]["product"] == "M3 bolt"
    # the real push, once the mesh is uploaded, gives the same diff
    upload(client, meshes, ("other",))
    a = put(client, scene, doc)
    assert a["dry_run"] is False and a["revision"] == 2 and "blas_to_build" not in a
    assert {k: a[k] for k in DIFF_KEYS} == {k: d[k] for k in DIFF_KEYS}
    assert a["blas_built"] + a["blas_loaded"] == len(d["blas_to_build"]) and a["blas_reused"] == d["blas_reused"]
    assert a["instances"] == d["instances"]
    assert nodes_of(client, scene)[uid(2)]["product"] is None
    # and a dry run of the way back lists what would be restored
    back = put(client, scene, assembly(meshes, base_revision=2, identity=identity()), dry_run=True)
    assert sorted((o["kind"], o["id"]) for o in back["restored"]) == [("light", light["id"]), ("material", uid(4))]
    assert back["removed"] == [uid(7)] and back["blas_to_build"] == [] and back["missing_geometries"] == []
    assert client.get(f"/scenes/{scene}").json()["revision"] == 2


def test_dry_run_of_the_current_tree_is_empty(client, scene, meshes) -> None:
    put(client, scene, assembly(meshes, identity=identity()))
    d = put(client, scene, assembly(meshes, base_revision=1, identity=identity(**{uid(2): None})), dry_run=True)
    assert d["dry_run"] is True and d["revision"] == 1 and d["unchanged"] == 7
    assert all(d[k] == [] for k in DIFF_KEYS if k != "unchanged")
    assert d["blas_to_build"] == [] and d["missing_geometries"] == []
    assert nodes_of(client, scene)[uid(2)]["product"] == "M3 bolt"  # the identity change was not stored


def test_dry_run_on_an_empty_scene_lists_every_mesh(client, scene, meshes) -> None:
    d = put(client, scene, car_document(meshes["other"][0], meshes["wheel"][0]), dry_run=True)
    assert len(d["added"]) == 8 and d["revision"] == 0
    assert d["missing_geometries"] == [meshes["other"][0]]
    assert d["blas_to_build"] == sorted([meshes["other"][0], meshes["wheel"][0]])
    assert client.get(f"/scenes/{scene}/nodes").json() == []
    assert client.get(f"/scenes/{scene}").json()["revision"] == 0


def test_dry_run_refuses_what_a_push_refuses(client, scene, meshes) -> None:
    put(client, scene, assembly(meshes, identity=identity()))
    put(client, scene, assembly(meshes, base_revision=1, bolt_x=1.0, identity=identity()))
    before = snapshot(client, scene)
    p = put(client, scene, assembly(meshes, base_revision=1, bolt_x=2.0), 409, dry_run=True)
    assert p["current_revision"] == 2
    # a real push from a stale base changes no identity record either
    changed = identity(**{uid(2): {"product": "M4 bolt", "signature": signature(20.0)}, uid(3): None})
    assert put(client, scene, assembly(meshes, base_revision=1, bolt_x=2.0, identity=changed), 409)[
        "current_revision"] == 2
    assert snapshot(client, scene) == before
    cyc = assembly(meshes, base_revision=2)
    cyc["nodes"][0]["parent"] = uid(1)
    put(client, scene, cyc, 422, dry_run=True)
    put(client, scene, b'{"nodes": [', 400, dry_run=True)
    put(client, scene, raw(assembly(meshes, base_revision=2, author="me")), 422, dry_run=True)
    assert snapshot(client, scene) == before
    assert client.put(f"/scenes/{UNKNOWN_ID}/document?dry_run=true", content=raw(assembly(meshes)),
                      headers=HDR).status_code == 404


def test_an_existing_database_is_migrated(tmp_path: Path) -> None:
    from alembic import command
    from alembic.config import Config

    from service import db

    url = f"sqlite:///{tmp_path / 'old.sqlite3'}"
    engine = db.open_engine(url, migrate=False)
    cfg = Config(str(db.MIGRATIONS / "alembic.ini"))
    cfg.set_main_option("script_location", str(db.MIGRATIONS))
    with engine.begin() as conn:
        cfg.attributes["connection"] = conn
        command.upgrade(cfg, "0001")
    with engine.begin() as conn:
        conn.execute(sa.insert(db.scenes).values(id="s", name="old", revision=3))
        assert "node_identity" not in sa.inspect(conn).get_table_names()
    db.upgrade(engine)
    with engine.connect() as conn:
        assert "node_identity" in sa.inspect(conn).get_table_names()
        assert conn.execute(sa.select(db.scenes.c.revision)).scalar() == 3
