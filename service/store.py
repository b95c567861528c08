"""Storage: every SQL statement of the sync service, one method per question or change (SQLAlchemy Core).

`SceneStore` knows tables and transactions, nothing of trees in memory or tracer scenes. Each change runs in
one transaction; those that keep a scene's revision count themselves in ``scenes.assign_revision``, guarded by
``WHERE revision = r AND assign_revision = a`` (`Raced` when another service process changed the scene in
between: the transaction rolls back and the caller reloads and tries again). A push's rows go in under
``UPDATE … WHERE revision = old`` (409 `Conflict` for the loser). See `service.db` for the tables.
"""

from __future__ import annotations

import uuid as uuidlib
from collections.abc import Iterable
from typing import Any

import numpy as np
from sqlalchemy import Engine, bindparam, delete, insert, select, update
from sqlalchemy.exc import IntegrityError

from service import db
from service.errors import Conflict
from service.schemas import IdentityIn

#: What `_identity_changes` answers: (records to insert, uuids whose rows to delete first, delete every row instead)
IdentityChanges = tuple[dict[str, IdentityIn], list[str], bool]

#: What a push changes in the memory of removed nodes: (uuid -> record to insert, uuids whose rows to delete)
RemovedChanges = tuple[dict[str, dict], list[str]]

#: The table of each kind of assignment, and the `SceneState` attribute that holds it in memory.
TABLES = {"light": (db.lights, "lights"), "sensor": (db.sensors, "sensors"), "object": (db.sim_objects, "objects"),
          "element": (db.element_assignments, "elements")}


class Raced(Conflict):
    """Another service process changed the scene between this process's check and its write (caught inside the
    service, which reloads and retries; a 409 if it ever got out)."""

    def __init__(self, scene_id: str) -> None:
        super().__init__(f"scene {scene_id} was changed by another service process meanwhile; retry")
        self.scene_id = scene_id


def color_of(c: tuple[float, float, float] | None) -> list[float] | None:
    return None if c is None else list(c)


def _blob(m: np.ndarray) -> bytes:
    return np.ascontiguousarray(m, dtype="<f8").tobytes()


class SceneStore:
    """The database behind every scene: scenes, nodes, assignments, identity records, revisions, geometries."""

    def __init__(self, engine: Engine) -> None:
        self.engine = engine

    # ------------------------------------------------------------ scenes

    def list_scenes(self) -> list[dict[str, Any]]:
        with self.engine.connect() as conn:
            rows = conn.execute(select(db.scenes.c.id, db.scenes.c.name, db.scenes.c.revision)
                                .order_by(db.scenes.c.created_at, db.scenes.c.name)).all()
        return [{"id": r.id, "name": r.name, "revision": r.revision} for r in rows]

    def create_scene(self, name: str) -> dict[str, Any]:
        scene_id = str(uuidlib.uuid4())
        try:
            with self.engine.begin() as conn:
                if conn.execute(select(db.scenes.c.id).where(db.scenes.c.name == name)).first() is not None:
                    raise Conflict(f"a scene named {name!r} exists already")
                conn.execute(insert(db.scenes).values(id=scene_id, name=name, revision=0))
        except IntegrityError as exc:  # created by another service process between the check and the insert
            raise Conflict(f"a scene named {name!r} exists already") from exc
        return {"id": scene_id, "name": name, "revision": 0}

    def delete_scene(self, scene_id: str) -> None:
        with self.engine.begin() as conn:
            for table in (db.materials, db.lights, db.sensors, db.sim_objects, db.node_identity, db.nodes,
                          db.removed_nodes, db.revisions):
                conn.execute(delete(table).where(table.c.scene_id == scene_id))
            conn.execute(delete(db.scenes).where(db.scenes.c.id == scene_id))

    def version(self, scene_id: str) -> tuple[int, int] | None:
        """``(revision, assign_revision)`` of the scene, or None if it has no row."""
        with self.engine.connect() as conn:
            row = conn.execute(select(db.scenes.c.revision, db.scenes.c.assign_revision)
                               .where(db.scenes.c.id == scene_id)).first()
        return None if row is None else (row.revision, row.assign_revision)

    def read_scene(self, scene_id: str) -> tuple[Any, list[Any], dict[str, Any]] | None:
        """(scene row, node rows in document order, `read_assignments`), or None if there is no such scene. The
        scene's row is read first: if another process commits while the rest is read, the rows are newer than
        the row's ``(revision, assign_revision)``, and the next version check reloads again."""
        with self.engine.connect() as conn:
            row = conn.execute(select(db.scenes).where(db.scenes.c.id == scene_id)).first()
            if row is None:
                return None
            node_rows = conn.execute(select(db.nodes).where(db.nodes.c.scene_id == scene_id)
                                     .order_by(db.nodes.c.position, db.nodes.c.uuid)).all()
            stored = self._read_assignments(conn, scene_id)
            stored["removed"] = {r.uuid: r.record for r in conn.execute(
                select(db.removed_nodes).where(db.removed_nodes.c.scene_id == scene_id)
                .order_by(db.removed_nodes.c.revision))}
            return row, list(node_rows), stored

    def read_assignments(self, scene_id: str) -> tuple[int, dict[str, Any]]:
        """(assign_revision, `read_assignments`) in one read."""
        with self.engine.connect() as conn:
            assign_revision = conn.execute(select(db.scenes.c.assign_revision)
                                           .where(db.scenes.c.id == scene_id)).scalar_one()
            return assign_revision, self._read_assignments(conn, scene_id)

    @staticmethod
    def _read_assignments(conn: Any, scene_id: str) -> dict[str, Any]:
        """The scene's assignments and identity records as stored."""
        out: dict[str, Any] = {
            "materials": {m.node: m.body for m in conn.execute(select(db.materials)
                                                               .where(db.materials.c.scene_id == scene_id))},
            "identity": {r.uuid: IdentityIn.model_validate({"product": r.product, "signature": r.signature})
                         for r in conn.execute(select(db.node_identity)
                                               .where(db.node_identity.c.scene_id == scene_id))}}
        for table, name in TABLES.values():
            out[name] = {r.id: r.body for r in conn.execute(
                select(table).where(table.c.scene_id == scene_id).order_by(table.c.created_at, table.c.id))}
        return out

    def source(self, scene_id: str) -> Any:
        with self.engine.connect() as conn:
            return conn.execute(select(db.scenes.c.source).where(db.scenes.c.id == scene_id)).scalar()

    def revisions(self, scene_id: str) -> list[dict[str, Any]]:
        with self.engine.connect() as conn:
            rows = conn.execute(select(db.revisions).where(db.revisions.c.scene_id == scene_id)
                                .order_by(db.revisions.c.revision)).all()
        return [{"revision": r.revision, "created_at": r.created_at.isoformat() if r.created_at else None,
                 **r.summary} for r in rows]

    # ------------------------------------------------------------ geometries

    def geometry_ids(self, ids: Iterable[str] | None = None) -> set[str]:
        """Every stored geometry id, or those of `ids` that are stored (500 per SELECT)."""
        with self.engine.connect() as conn:
            if ids is None:
                return set(conn.execute(select(db.geometries.c.id)).scalars())
            wanted, out = list(ids), set[str]()
            for i in range(0, len(wanted), 500):
                out.update(conn.execute(select(db.geometries.c.id)
                                        .where(db.geometries.c.id.in_(wanted[i:i + 500]))).scalars())
            return out

    def add_geometry(self, gid: str, n_vertices: int, n_triangles: int, has_normals: bool, size_bytes: int) -> None:
        """Record a stored mesh (idempotent, also against another service process storing it at once)."""
        try:
            with self.engine.begin() as conn:
                if conn.execute(select(db.geometries.c.id).where(db.geometries.c.id == gid)).first() is None:
                    conn.execute(insert(db.geometries).values(id=gid, n_vertices=n_vertices, n_triangles=n_triangles,
                                                              has_normals=has_normals, size_bytes=size_bytes))
        except IntegrityError:
            pass

    def triangles(self, counts: dict[str, int]) -> int:
        """Triangles of `counts` ({geometry id: instances})."""
        if not counts:
            return 0
        with self.engine.connect() as conn:
            tri = dict(conn.execute(select(db.geometries.c.id, db.geometries.c.n_triangles)
                                    .where(db.geometries.c.id.in_(list(counts)))).all())
        return sum(tri.get(g, 0) * k for g, k in counts.items())

    # ------------------------------------------------------------ changes that keep the revision

    @staticmethod
    def _bump(conn: Any, scene_id: str, revision: int, assign_revision: int) -> None:
        """In the caller's transaction: count one change that keeps the revision, provided the database still
        holds the scene at ``(revision, assign_revision)`` (else `Raced`: the transaction rolls back)."""
        c = db.scenes.c
        res = conn.execute(update(db.scenes).where(c.id == scene_id).where(c.revision == revision)
                           .where(c.assign_revision == assign_revision).values(assign_revision=assign_revision + 1))
        if res.rowcount != 1:
            raise Raced(scene_id)

    def set_material(self, scene_id: str, version: tuple[int, int], key: str, body: dict) -> None:
        with self.engine.begin() as conn:
            self._bump(conn, scene_id, *version)
            conn.execute(delete(db.materials).where(db.materials.c.scene_id == scene_id)
                         .where(db.materials.c.node == key))
            conn.execute(insert(db.materials).values(scene_id=scene_id, node=key, body=body))

    def delete_material(self, scene_id: str, version: tuple[int, int], key: str) -> None:
        with self.engine.begin() as conn:
            self._bump(conn, scene_id, *version)
            conn.execute(delete(db.materials).where(db.materials.c.scene_id == scene_id)
                         .where(db.materials.c.node == key))

    def add_assignment(self, scene_id: str, version: tuple[int, int], kind: str, aid: str, body: dict,
                       material: dict | None = None) -> None:
        """A light, sensor or object (with its own material, for an object) under id `aid`."""
        with self.engine.begin() as conn:
            self._bump(conn, scene_id, *version)
            conn.execute(insert(TABLES[kind][0]).values(id=aid, scene_id=scene_id, body=body))
            if material is not None:
                conn.execute(insert(db.materials).values(scene_id=scene_id, node=aid, body=material))

    def replace_assignment(self, scene_id: str, version: tuple[int, int], kind: str, aid: str, body: dict) -> None:
        """Assignment `aid` takes `body` (an element assignment switched to another element)."""
        table = TABLES[kind][0]
        with self.engine.begin() as conn:
            self._bump(conn, scene_id, *version)
            conn.execute(update(table).where(table.c.id == aid).values(body=body))

    def delete_assignment(self, scene_id: str, version: tuple[int, int], kind: str, aid: str) -> None:
        table = TABLES[kind][0]
        with self.engine.begin() as conn:
            self._bump(conn, scene_id, *version)
            conn.execute(delete(table).where(table.c.id == aid))
            if kind == "object":
                conn.execute(delete(db.materials).where(db.materials.c.scene_id == scene_id)
                             .where(db.materials.c.node == aid))

    def store_identity(self, scene_id: str, version: tuple[int, int], changes: IdentityChanges) -> None:
        """Only identity records changed (a push whose tree is unchanged): stored, no new revision."""
        with self.engine.begin() as conn:
            self._bump(conn, scene_id, *version)
            _write_identity(conn, scene_id, *changes)

    def store_order(self, scene_id: str, version: tuple[int, int], uuids: list[str], old_index: dict[str, int],
                    identity_changes: IdentityChanges | None = None) -> None:
        """A push that only reorders the node list (no new revision): the positions of the rows that moved, so
        that a restart gives same-named siblings the [k] ranks this order gives them."""
        c = db.nodes.c
        rows = [{"u": u, "p": float(j)} for j, u in enumerate(uuids) if old_index.get(u) != j]
        with self.engine.begin() as conn:
            self._bump(conn, scene_id, *version)
            if rows:
                conn.execute(update(db.nodes).where(c.scene_id == scene_id).where(c.uuid == bindparam("u"))
                             .values(position=bindparam("p")), rows)
            if identity_changes is not None:
                _write_identity(conn, scene_id, *identity_changes)

    # ------------------------------------------------------------ a push

    def store_push(self, scene_id: str, revision: int, length_unit: str, source: dict | None, old: Any, new: Any,
                   diff: Any, summary: dict[str, Any], identity_changes: IdentityChanges | None,
                   removed_changes: RemovedChanges | None = None) -> None:
        """Write a push as revision ``revision + 1``: the scene row (guarded: 409 if another writer got there
        first), the changed node rows of `new` (a `service.tree.Tree`) against `old`, the identity records and
        the revision's summary, in one transaction."""
        c = db.nodes.c
        with self.engine.begin() as conn:
            res = conn.execute(update(db.scenes).where(db.scenes.c.id == scene_id)
                               .where(db.scenes.c.revision == revision)
                               .values(revision=revision + 1, length_unit=length_unit, source=source))
            if res.rowcount != 1:
                current = conn.execute(select(db.scenes.c.revision).where(db.scenes.c.id == scene_id)).scalar()
                raise Conflict(f"the scene changed under this push (now at revision {current})",
                               current_revision=current)
            gone = list(diff.removed) + [u for u in diff.upserts if u in old.index]
            for i in range(0, len(gone), 500):
                conn.execute(delete(db.nodes).where(c.scene_id == scene_id).where(c.uuid.in_(gone[i:i + 500])))
            # document order: rows whose place in the node list changed (a reorder, a removal before them) get
            # their new position, so that a restart orders siblings (and their [k] ranks) as this push did
            if old.uuids != new.uuids:
                moved_rows = [{"u": u, "p": float(j)} for j, u in enumerate(new.uuids)
                              if u not in diff.upserts and old.index.get(u) != j]
                if moved_rows:
                    conn.execute(update(db.nodes).where(c.scene_id == scene_id).where(c.uuid == bindparam("u"))
                                 .values(position=bindparam("p")), moved_rows)
            if diff.upserts:
                rows = []
                for u in diff.upserts:
                    j = new.index[u]
                    rows.append({"scene_id": scene_id, "uuid": u, "position": float(j), "parent": new.parents[j],
                                 "name": new.names[j], "transform": _blob(new.local[j]),
                                 "geometry": new.geometries[j], "color": color_of(new.colors[j])})
                conn.execute(insert(db.nodes), rows)
            if identity_changes is not None:
                _write_identity(conn, scene_id, *identity_changes)
            if removed_changes is not None:
                _write_removed(conn, scene_id, revision + 1, *removed_changes)
            conn.execute(insert(db.revisions).values(scene_id=scene_id, revision=revision + 1, summary=summary))


def _write_identity(conn: Any, scene_id: str, write: dict[str, IdentityIn], drop: list[str], clear: bool) -> None:
    """Apply an `IdentityChanges` to the ``node_identity`` table on `conn` (inside the caller's transaction)."""
    c = db.node_identity.c
    if clear:
        conn.execute(delete(db.node_identity).where(c.scene_id == scene_id))
    for i in range(0, len(drop), 500):
        conn.execute(delete(db.node_identity).where(c.scene_id == scene_id).where(c.uuid.in_(drop[i:i + 500])))
    if write:
        conn.execute(insert(db.node_identity), [
            {"scene_id": scene_id, "uuid": u, "product": r.product,
             "signature": r.signature.model_dump(exclude_none=True) if r.signature is not None else None}
            for u, r in write.items()])


def _write_removed(conn: Any, scene_id: str, revision: int, write: dict[str, dict], drop: list[str]) -> None:
    """Apply a `RemovedChanges` to ``removed_nodes`` on `conn` (inside the push's transaction)."""
    import datetime as dt

    c = db.removed_nodes.c
    gone = list(drop) + list(write)
    for i in range(0, len(gone), 500):
        conn.execute(delete(db.removed_nodes).where(c.scene_id == scene_id).where(c.uuid.in_(gone[i:i + 500])))
    if write:
        conn.execute(insert(db.removed_nodes), [
            {"scene_id": scene_id, "uuid": u, "revision": revision, "record": r,
             "removed_at": dt.datetime.fromisoformat(r["removed_at"])} for u, r in write.items()])


def normalize_positions(engine: Engine, scene_id: str, rows: list[Any]) -> None:
    """Store positions 0, 1, … for node rows read in document order (`read_scene`), where they are not: older
    pushes left gaps and ties that a push's `store_push` (which writes row numbers) could collide with."""
    fix = [{"u": r.uuid, "p": float(j)} for j, r in enumerate(rows) if r.position != float(j)]
    if fix:
        c = db.nodes.c
        with engine.begin() as conn:
            conn.execute(update(db.nodes).where(c.scene_id == scene_id).where(c.uuid == bindparam("u"))
                         .values(position=bindparam("p")), fix)
