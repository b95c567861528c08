"""The sync service's core: scenes in memory and in the database, pushes, assignments, live views.

`SceneManager` owns, per scene, the current `Tree`, the committed `tracer.Scene`, the instance
id of every node with geometry and every assignment (materials, lights, sensors, sim-owned
objects, all keyed by uuid). Every change runs under the scene's lock:

- a push decodes and validates the document, checks ``base_revision``, diffs it against the
  current tree, applies the diff to the tracer scene (BLAS for new geometry, top level for the
  rest), then writes the changed rows and the revision in one transaction whose
  ``UPDATE … WHERE revision = old`` guards against a writer in another process. If the store
  fails, the in-memory scene is dropped and reloaded from the database on next use, so memory
  never runs ahead of what was committed. Decoding reuses the previous push's bytes
  (`service.document`): a byte-identical node list is recognised by one comparison, and
  otherwise only the nodes between the common prefix and suffix are parsed, so the cost of a
  push follows what changed plus a few linear, vectorized passes.
- a push also carries the nodes' identity records (product name, shape signature; what the CAD
  adapter matches the next document by, served back by `nodes`). They are kept per node uuid in
  memory and in ``node_identity``; a push compares them with the stored ones in memory and writes
  only those that changed (in the push's transaction, or on their own when the tree is unchanged:
  no new revision). A dry run (`push(..., dry_run=True)`) decodes, validates and diffs the same
  way and answers what the push would do, changing nothing.
- after a restart a scene is loaded on first use: tree, identity records, assignments, and a tracer
  scene whose bottom levels come from the BLAS cache under the data directory (none rebuilt if intact).
- several service processes may share one database (and one data directory: the mesh store and the
  BLAS cache). Every use of a scene (`state`) compares ``(revision, assign_revision)`` in the database
  with the scene in memory — one SELECT of one row — and catches up when the database is ahead: a newer
  revision reloads the scene as after a restart; a newer ``assign_revision`` (another process changed an
  assignment or only identity records) reloads those tables in place and moves sim objects' instances.
  Listeners hear of it as of any change. Each change is guarded in its own transaction: a push by
  ``UPDATE … WHERE revision = old`` (the loser gets 409 and its scene is reloaded), an assignment by
  ``UPDATE … WHERE revision = r AND assign_revision = a`` (on a lost race the scene is reloaded and the
  change tried again on it).

Domain errors are raised as `service.errors` exceptions; the routes stay thin.
"""

from __future__ import annotations

import contextlib
import copy
import functools
import gc
import logging
import threading
import time
import uuid as uuidlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from pydantic import TypeAdapter
from sqlalchemy import Engine, delete, insert, select, update
from sqlalchemy.exc import IntegrityError

from service import db
from service.config import Settings
from service.document import (
    NodeBytes,
    count_nodes,
    decode_document,
    decode_incremental,
    remember,
    same_nodes,
)
from service.errors import Conflict, Invalid, NotFound, TooLarge, Unavailable
from service.live import DELETED, LiveRegistry, LiveScene
from service.meshes import MeshStore
from service.schemas import LENGTH_UNITS, DocumentPush, IdentityIn, Light, Material, ObjectCreate, Sensor
from service.tree import Tree, TreeDiff, TreeError, apply_to_scene, diff_trees

log = logging.getLogger("lumenlink.service")

DEFAULT_MATERIAL: dict[str, Any] = {"type": "lambertian", "reflectance": 0.5}

material_adapter: TypeAdapter = TypeAdapter(Material)
light_adapter: TypeAdapter = TypeAdapter(Light)
sensor_adapter: TypeAdapter = TypeAdapter(Sensor)


class _Raced(Exception):
    """Another service process changed the scene between this process's check and its write."""

    def __init__(self, scene_id: str) -> None:
        super().__init__(scene_id)
        self.scene_id = scene_id


RACE_TRIES = 3


def _retried(method: Callable[..., Any]) -> Callable[..., Any]:
    """Run an assignment change again on the reloaded scene when another process changed the scene between
    this one's check and its guarded write (`SceneManager._bump_assignments`); 409 after `RACE_TRIES` tries."""

    @functools.wraps(method)
    def run(self: SceneManager, scene_id: str, *args: Any, **kwargs: Any) -> Any:
        for _ in range(RACE_TRIES):
            try:
                return method(self, scene_id, *args, **kwargs)
            except _Raced:
                self.forget(scene_id)   # memory may be ahead of the database (an object placed): reload it
        raise Conflict(f"scene {scene_id} kept changing through other service processes during this change "
                       f"({RACE_TRIES} tries); nothing was changed, try again")

    return run


@contextlib.contextmanager
def gc_paused() -> Iterator[None]:
    """Pause the cyclic garbage collector: decoding a 20k-node document allocates ~10^6 objects,
    and generation-2 passes over them would otherwise cost more than the decode itself."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()


def _color(c: tuple[float, float, float] | None) -> list[float] | None:
    return None if c is None else list(c)


def _blob(m: np.ndarray) -> bytes:
    return np.ascontiguousarray(m, dtype="<f8").tobytes()


@dataclass
class SceneState:
    """One scene in memory (guarded by `lock`)."""

    id: str
    name: str
    revision: int
    length_unit: str | None
    tree: Tree
    tracer: Any
    assign_revision: int = 0  # scenes.assign_revision this memory reflects (see service.db)
    instances: dict[str, int] = field(default_factory=dict)  # document node uuid -> instance
    object_instances: dict[str, int] = field(default_factory=dict)  # sim object id -> instance
    geometries: set[str] = field(default_factory=set)  # geometry ids added to `tracer`
    materials: dict[str, dict] = field(default_factory=dict)  # node uuid / object id -> material body
    lights: dict[str, dict] = field(default_factory=dict)  # id -> body as given
    sensors: dict[str, dict] = field(default_factory=dict)
    objects: dict[str, dict] = field(default_factory=dict)
    last_commit: dict[str, Any] = field(default_factory=dict)
    node_bytes: NodeBytes | None = None  # where each node sits in the body that made `tree` (row i = chunk i)
    identity: dict[str, IdentityIn] = field(default_factory=dict)  # node uuid -> its identity record, as stored
    live: LiveScene | None = None
    lock: threading.RLock = field(default_factory=threading.RLock)

    # ------------------------------------------------------------ references to nodes

    def has_node(self, key: str) -> bool:
        return key in self.tree.index

    def anchor_of(self, body: dict) -> str | None:
        """The node a light/sensor/object body depends on (attached_to, or an area light's node)."""
        return body.get("attached_to") or (body.get("node") if body.get("type") == "area" else None)

    def orphans(self, only_nodes: set[str] | None = None) -> list[dict[str, str]]:
        """Assignments whose node is not in the tree (optionally only those naming `only_nodes`)."""
        out: list[dict[str, str]] = []

        def missing(node: str | None) -> bool:
            if node is None:
                return False
            if only_nodes is not None:
                return node in only_nodes
            return not self.has_node(node) and node not in self.objects

        for key in self.materials:
            if missing(key) and key not in self.objects:
                out.append({"kind": "material", "id": key, "node": key})
        for kind, table in (("light", self.lights), ("sensor", self.sensors), ("object", self.objects)):
            for aid, body in table.items():
                node = self.anchor_of(body)
                if missing(node):
                    out.append({"kind": kind, "id": aid, "node": node})  # type: ignore[dict-item]
        return out


class SceneManager:
    """All scenes of this process, backed by the database and the mesh store."""

    def __init__(self, settings: Settings, engine: Engine, meshes: MeshStore,
                 scene_factory: Callable[[], Any] | None = None) -> None:
        self.settings = settings
        self.engine = engine
        self.meshes = meshes
        self._scene_factory = scene_factory
        self._states: dict[str, SceneState] = {}
        self._lock = threading.Lock()
        self._scene_locks: dict[str, threading.RLock] = {}
        self.live = LiveRegistry(self.live_scene, self.revision, lambda scene_id: self.state(scene_id).lock)
        with engine.connect() as conn:
            self._known_geometries: set[str] = set(conn.execute(select(db.geometries.c.id)).scalars())

    # ------------------------------------------------------------ tracer scenes

    def new_tracer_scene(self) -> Any:
        if self._scene_factory is not None:
            return self._scene_factory()
        import tracer  # imported on first use: numba start-up is not paid by /health

        cache = self.settings.blas_dir
        cache.mkdir(parents=True, exist_ok=True)
        return tracer.Scene(cache_dir=cache)

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
        with self._current(scene_id):
            with self.engine.begin() as conn:
                for table in (db.materials, db.lights, db.sensors, db.sim_objects, db.node_identity, db.nodes,
                              db.revisions):
                    conn.execute(delete(table).where(table.c.scene_id == scene_id))
                conn.execute(delete(db.scenes).where(db.scenes.c.id == scene_id))
            with self._lock:
                self._states.pop(scene_id, None)
            self.live.notify(scene_id, DELETED)   # its results go stale and its jobs are cancelled

    def revision(self, scene_id: str) -> int:
        return self.state(scene_id).revision

    def state(self, scene_id: str) -> SceneState:
        """The in-memory scene, current with the database (NotFound if there is none).

        Loaded on first use; afterwards one SELECT compares the scene's ``(revision, assign_revision)``
        in the database with memory, and a scene another service process changed is brought up to date
        first (under the scene's lock): reloaded for a newer revision, its assignments reloaded for a newer
        ``assign_revision``, dropped (NotFound) if it was deleted.
        """
        state = self._states.get(scene_id)
        if state is not None and self._version(scene_id) == (state.revision, state.assign_revision):
            return state
        lock = self._scene_lock(scene_id)
        with lock:
            state = self._states.get(scene_id)
            if state is None:
                state = self._load(scene_id, lock)
                with self._lock:
                    self._states[scene_id] = state
                return state
            version = self._version(scene_id)
            if version == (state.revision, state.assign_revision):  # a change by this process, done meanwhile
                return state
            if version is None:  # deleted through another process
                with self._lock:
                    self._states.pop(scene_id, None)
                self.live.notify(scene_id, DELETED)
                raise NotFound(f"no scene {scene_id}")
            log.info("scene %s changed in the database (revision %d, assignments %d; this process had %d, %d): "
                     "catching up", scene_id, version[0], version[1], state.revision, state.assign_revision)
            try:
                if version[0] == state.revision:
                    self._reload_assignments(state)
                else:
                    state = self._load(scene_id, lock)
                    with self._lock:
                        self._states[scene_id] = state
            except Exception:
                self.forget(scene_id)
                raise
            self.live.notify(scene_id, state.revision)
            return state

    @contextlib.contextmanager
    def _current(self, scene_id: str) -> Iterator[SceneState]:
        """The scene's lock held, and the scene brought up to date under it (for a change)."""
        with self._scene_lock(scene_id):
            yield self.state(scene_id)

    def _scene_lock(self, scene_id: str) -> threading.RLock:
        with self._lock:
            return self._scene_locks.setdefault(scene_id, threading.RLock())

    def _version(self, scene_id: str) -> tuple[int, int] | None:
        """``(revision, assign_revision)`` of the scene in the database, or None if it has no row."""
        with self.engine.connect() as conn:
            row = conn.execute(select(db.scenes.c.revision, db.scenes.c.assign_revision)
                               .where(db.scenes.c.id == scene_id)).first()
        return None if row is None else (row.revision, row.assign_revision)

    def forget(self, scene_id: str) -> None:
        """Drop the in-memory scene; the next use reloads it from the database."""
        with self._lock:
            self._states.pop(scene_id, None)

    @staticmethod
    def _read_assignments(conn: Any, scene_id: str) -> dict[str, Any]:
        """The scene's assignments and identity records as stored."""
        out: dict[str, Any] = {
            "materials": {m.node: m.body for m in conn.execute(select(db.materials)
                                                               .where(db.materials.c.scene_id == scene_id))},
            "identity": {r.uuid: IdentityIn.model_validate({"product": r.product, "signature": r.signature})
                         for r in conn.execute(select(db.node_identity)
                                               .where(db.node_identity.c.scene_id == scene_id))}}
        for name, table in (("lights", db.lights), ("sensors", db.sensors), ("objects", db.sim_objects)):
            out[name] = {r.id: r.body for r in conn.execute(
                select(table).where(table.c.scene_id == scene_id).order_by(table.c.created_at, table.c.id))}
        return out

    def _load(self, scene_id: str, lock: threading.RLock) -> SceneState:
        # the scene's row is read first: if another process commits while the rest is read, memory holds
        # newer rows under an older (revision, assign_revision), and the next `state` reloads again
        with self.engine.connect() as conn:
            row = conn.execute(select(db.scenes).where(db.scenes.c.id == scene_id)).first()
            if row is None:
                raise NotFound(f"no scene {scene_id}")
            node_rows = conn.execute(select(db.nodes).where(db.nodes.c.scene_id == scene_id)
                                     .order_by(db.nodes.c.position)).all()
            stored = self._read_assignments(conn, scene_id)
        unit = row.length_unit or "m"
        transforms = (np.frombuffer(b"".join(r.transform for r in node_rows), dtype="<f8").reshape(-1, 16)
                      if node_rows else np.zeros((0, 16)))
        tree = Tree.build([r.uuid for r in node_rows], [r.parent for r in node_rows], [r.name for r in node_rows],
                          transforms, [r.geometry for r in node_rows],
                          [tuple(r.color) if r.color is not None else None for r in node_rows], unit)
        state = SceneState(scene_id, row.name, row.revision, row.length_unit, Tree.empty(unit),
                           self.new_tracer_scene(), assign_revision=row.assign_revision,
                           materials=stored["materials"], lights=stored["lights"], sensors=stored["sensors"],
                           objects=stored["objects"], lock=lock, identity=stored["identity"])
        diff = diff_trees(state.tree, tree)
        state.tree = tree
        apply_to_scene(state.tracer, state.instances, tree, diff, lambda g: self._ensure_geometry(state, g))
        for oid, body in state.objects.items():
            self._place_object(state, oid, body)
        state.last_commit = self._commit(state)
        log.info("loaded scene %s (revision %d, %d nodes): %s", scene_id, state.revision, len(tree),
                 state.last_commit)
        return state

    def _reload_assignments(self, state: SceneState) -> None:
        """Bring the assignments and identity records of `state` (tree unchanged) up to the database's, in place:
        sim objects gone or new get their instances removed or added (one top-level commit if any did)."""
        with self.engine.connect() as conn:
            assign_revision = conn.execute(select(db.scenes.c.assign_revision)
                                           .where(db.scenes.c.id == state.id)).scalar_one()
            stored = self._read_assignments(conn, state.id)
        moved = False
        for oid, body in state.objects.items():
            if stored["objects"].get(oid) != body:
                inst = state.object_instances.pop(oid, None)
                if inst is not None:
                    state.tracer.remove_instance(inst)
                    moved = True
        for oid, body in stored["objects"].items():
            if oid not in state.object_instances:
                self._place_object(state, oid, body)
                moved = moved or oid in state.object_instances
        if moved:
            state.last_commit = self._commit(state)
        state.materials, state.lights, state.sensors = stored["materials"], stored["lights"], stored["sensors"]
        state.objects, state.identity = stored["objects"], stored["identity"]
        state.assign_revision = assign_revision
        state.live = None

    def _bump_assignments(self, conn: Any, state: SceneState) -> None:
        """In the caller's transaction: count one change that keeps the revision, provided the database still
        holds the scene as `state` does (else `_Raced`: the caller's transaction rolls back)."""
        c = db.scenes.c
        res = conn.execute(update(db.scenes).where(c.id == state.id).where(c.revision == state.revision)
                           .where(c.assign_revision == state.assign_revision)
                           .values(assign_revision=state.assign_revision + 1))
        if res.rowcount != 1:
            raise _Raced(state.id)

    # ------------------------------------------------------------ geometry

    def _look_up_geometries(self, ids: Any) -> None:
        """Add to the known geometries those of `ids` that another service process stored (one SELECT)."""
        unknown = list({g for g in ids if isinstance(g, str) and g not in self._known_geometries})
        if not unknown:
            return
        with self.engine.connect() as conn:
            for i in range(0, len(unknown), 500):
                self._known_geometries.update(conn.execute(
                    select(db.geometries.c.id).where(db.geometries.c.id.in_(unknown[i:i + 500]))).scalars())

    def known_geometries(self, ids: list[str]) -> set[str]:
        self._look_up_geometries(ids)
        return {g for g in ids if g in self._known_geometries}

    def missing_geometries(self, ids: list[str]) -> list[str]:
        self._look_up_geometries(ids)
        seen: set[str] = set()
        out = []
        for g in ids:
            if g not in self._known_geometries and g not in seen:
                seen.add(g)
                out.append(g)
        return out

    def put_geometry(self, gid: str, data: bytes) -> dict[str, Any]:
        """Store an uploaded GLB (idempotent): 400 if it does not hash to `gid`, 422 if it is no valid mesh."""
        mesh = self.meshes.validate_upload(gid, data)
        self._look_up_geometries([gid])
        created = gid not in self._known_geometries or not self.meshes.has(gid)
        if created:
            self.meshes.write(gid, data, mesh)
            try:
                with self.engine.begin() as conn:
                    exists = conn.execute(select(db.geometries.c.id).where(db.geometries.c.id == gid)).first()
                    if exists is None:
                        conn.execute(insert(db.geometries).values(
                            id=gid, n_vertices=len(mesh.vertices), n_triangles=len(mesh.triangles),
                            has_normals=mesh.normals is not None, size_bytes=len(data)))
            except IntegrityError:  # the same mesh stored by another service process at the same moment
                pass
            self._known_geometries.add(gid)
        return {"id": gid, "vertices": len(mesh.vertices), "triangles": len(mesh.triangles),
                "normals": mesh.normals is not None, "bytes": len(data), "created": created}

    def geometry_glb(self, gid: str) -> bytes:
        self._look_up_geometries([gid])
        if gid not in self._known_geometries:
            raise NotFound(f"no geometry {gid}")
        return self.meshes.glb(gid)

    def _ensure_geometry(self, state: SceneState, gid: str) -> bool:
        if gid in state.geometries:
            return False
        if not self.meshes.has(gid):
            # stored by another service process whose data directory this one does not share
            raise Unavailable(f"geometry {gid} is in the database but not in this process's mesh store "
                              f"({self.meshes.root}): every service process on one database must share one data "
                              f"directory (LUMENLINK_DATA_DIR)", geometry=gid)
        mesh = self.meshes.load(gid)
        got = state.tracer.add_geometry(mesh.vertices, mesh.triangles, mesh.normals)
        if got != gid:
            raise RuntimeError(f"tracer gave geometry id {got} for stored mesh {gid}")
        state.geometries.add(gid)
        return True

    def _commit(self, state: SceneState) -> dict[str, Any]:
        stats = state.tracer.commit()
        return {"blas_built": int(getattr(stats, "blas_built", 0)),
                "blas_loaded": int(getattr(stats, "blas_loaded", 0)),
                "blas_seconds": float(getattr(stats, "blas_seconds", 0.0)),
                "tlas_seconds": float(getattr(stats, "tlas_seconds", 0.0))}

    # ------------------------------------------------------------ sim-owned objects in the tracer scene

    def _object_transform(self, state: SceneState, body: dict) -> np.ndarray | None:
        """world_from_mesh of a sim object, or None while its node is missing (orphaned)."""
        t = np.asarray(body["transform"], dtype=np.float64).reshape(4, 4)
        s = LENGTH_UNITS[body.get("mesh_unit", "m")]
        t = t @ np.diag([s, s, s, 1.0])
        node = body.get("attached_to")
        if node is None:
            return t
        row = state.tree.index.get(node)
        if row is None:
            return None
        return state.tree.world[row] @ t

    def _place_object(self, state: SceneState, oid: str, body: dict) -> None:
        """Add, move or remove the object's instance so it matches the tree (call before commit)."""
        t = self._object_transform(state, body)
        inst = state.object_instances.get(oid)
        if t is None:
            if inst is not None:
                state.tracer.remove_instance(inst)
                del state.object_instances[oid]
            return
        if inst is None:
            self._ensure_geometry(state, body["geometry"])
            state.object_instances[oid] = state.tracer.add_instance(body["geometry"], t)
        else:
            state.tracer.set_transform(inst, t)

    # ------------------------------------------------------------ push

    def push(self, scene_id: str, body: bytes, dry_run: bool = False) -> dict[str, Any]:
        """Validate, diff, apply and store one pushed document; the answer of ``PUT /scenes/{id}/document``.

        With `dry_run` the body is decoded, validated and diffed exactly as for a push (a stale
        ``base_revision`` is still 409, an invalid body still 4xx), but nothing changes — not the
        database, the tree, the tracer scene, the identity records nor the live view — and
        geometries not uploaded yet are listed (``missing_geometries``) instead of refused.
        """
        t0 = time.perf_counter()
        state = self.state(scene_id)  # 404 before any work
        counted = count_nodes(body)   # a too-large tree is refused from its bytes: no decoding, no lock taken
        if counted > self.settings.max_nodes:
            raise TooLarge(f"the document has {counted} nodes; this service accepts at most "
                           f"{self.settings.max_nodes} (LUMENLINK_MAX_NODES)", limit=self.settings.max_nodes)
        with state.lock, gc_paused():
            state = self.state(scene_id)  # up to date under the lock (changed through another process, reloaded)
            node_bytes = state.node_bytes
            missing: list[str] = []
            doc = same_nodes(body, node_bytes) if node_bytes is not None else None
            if doc is not None and doc.length_unit == state.tree.length_unit:
                # byte-identical node list: the tree is the current one
                new = state.tree
                t_decode = time.perf_counter()
            else:
                inc = None
                if state.node_bytes is not None:  # decode only the nodes whose bytes changed
                    inc = decode_incremental(body, state.node_bytes, state.tree, self._known_geometries)
                if inc is not None:
                    decoded, node_bytes = inc
                else:
                    decoded = decode_document(body, state.tree.index, self._known_geometries)  # ValidationError
                    node_bytes = None
                doc = decoded.header
                t_decode = time.perf_counter()
                if len(decoded.uuids) > self.settings.max_nodes:   # a node list that is not the last member
                    raise TooLarge(f"the document has {len(decoded.uuids)} nodes; this service accepts at most "
                                   f"{self.settings.max_nodes} (LUMENLINK_MAX_NODES)", limit=self.settings.max_nodes)
                try:
                    new = Tree.build(*decoded.columns(), doc.length_unit, like=state.tree)
                except TreeError as exc:
                    raise Invalid(str(exc), problems=exc.problems[:100]) from exc
                missing = sorted(self.missing_geometries([g for g in set(new.geometries) if g is not None]))
                if missing and not dry_run:
                    raise Invalid(f"{len(missing)} geometry id(s) are not uploaded yet (PUT /geometries/{{id}} "
                                  f"first)", missing=missing)
            identity = _identity_of(doc, new)  # 422 naming a key that is no node of this push
            if dry_run:
                return self._dry_run_locked(state, doc, new, missing, t0, t_decode)
            answer = self._push_locked(state, doc, new, identity, t0, t_decode)
            # the tree is now exactly what these bytes describe, row for row
            state.node_bytes = node_bytes if node_bytes is not None else remember(body, state.tree.names)
            return answer

    def _diff(self, state: SceneState, doc: DocumentPush, new: Tree) -> TreeDiff:
        """The push's diff against the current tree; 409 if it changes the tree from a stale ``base_revision``."""
        diff = diff_trees(state.tree, new)
        if state.length_unit is None and len(new) == 0 and doc.length_unit != state.tree.length_unit:
            diff.length_unit_changed = False
        if doc.base_revision is not None and doc.base_revision != state.revision and not diff.is_empty():
            raise Conflict(f"base_revision {doc.base_revision} is stale: the scene is at revision {state.revision}",
                           current_revision=state.revision)
        return diff

    def _dry_run_locked(self, state: SceneState, doc: DocumentPush, new: Tree, missing: list[str], t0: float,
                        t_decode: float) -> dict[str, Any]:
        """What `_push_locked` would answer, computed without changing anything."""
        t_validate = time.perf_counter()
        diff = self._diff(state, doc, new)
        t_diff = time.perf_counter()
        added, removed = set(diff.added), set(diff.removed)
        orphaned = state.orphans(only_nodes=removed) if removed else []
        restored = state.orphans(only_nodes=added) if added else []
        # the geometries `apply_to_scene` would add to the tracer scene, and those it would find there
        to_build: set[str] = set()
        reused: set[str] = set()
        wanted = [new.geometries[new.index[u]] for u in list(diff.added) + diff.geometry_changed]
        wanted += [body["geometry"] for body in state.objects.values() if body.get("attached_to") in added]
        for g in wanted:
            if g is not None:
                (reused if g in state.geometries else to_build).add(g)
        instances = sum(1 for g in new.geometries if g is not None) + sum(
            1 for body in state.objects.values()
            if body.get("attached_to") is None or body["attached_to"] in new.index)
        seconds = {"decode": t_decode - t0, "validate": t_validate - t_decode, "diff": t_diff - t_validate,
                   "blas": 0.0, "tlas": 0.0, "commit": 0.0, "store": 0.0}
        seconds["total"] = time.perf_counter() - t0
        out = self._answer(state, doc, diff, {}, seconds, orphaned, restored, blas_reused=len(reused))
        out.update(instances=instances, dry_run=True, blas_to_build=sorted(to_build), missing_geometries=missing)
        return out

    def _push_locked(self, state: SceneState, doc: DocumentPush, new: Tree, identity: dict[str, IdentityIn], t0: float,
                     t_decode: float) -> dict[str, Any]:
        t_validate = time.perf_counter()
        diff = self._diff(state, doc, new)
        t_diff = time.perf_counter()
        changes = _identity_changes(state.identity, identity)
        if diff.is_empty():
            state.tree = new  # the same tree; its rows now follow this body's order
            t_store = time.perf_counter()
            if changes is not None:  # only the identity records changed: stored, no new revision
                try:
                    with self.engine.begin() as conn:
                        self._bump_assignments(conn, state)
                        _store_identity(conn, state.id, *changes)
                except _Raced as exc:
                    self.forget(state.id)
                    now = self._version(state.id)
                    current = now[0] if now is not None else None
                    raise Conflict(f"the scene changed under this push through another service process (now at "
                                   f"revision {current})", current_revision=current) from exc
                except Exception:
                    self.forget(state.id)
                    raise
                state.identity = identity
                state.assign_revision += 1
            seconds = {"decode": t_decode - t0, "validate": t_validate - t_decode, "diff": t_diff - t_validate,
                       "blas": 0.0, "tlas": 0.0, "commit": 0.0, "store": time.perf_counter() - t_store}
            seconds["total"] = time.perf_counter() - t0
            return self._answer(state, doc, diff, {}, seconds, [], [], blas_reused=0)

        old_tree = state.tree
        removed = set(diff.removed)
        added = set(diff.added)
        try:
            t_apply = time.perf_counter()
            load_seconds = [0.0]

            def ensure(gid: str) -> bool:
                tl = time.perf_counter()
                try:
                    return self._ensure_geometry(state, gid)
                finally:
                    load_seconds[0] += time.perf_counter() - tl

            apply_stats = apply_to_scene(state.tracer, state.instances, new, diff, ensure)
            state.tree = new
            moved = set(diff.moved)
            for oid, body in state.objects.items():
                node = body.get("attached_to")
                if node is not None and (node in moved or node in removed or node in added):
                    self._place_object(state, oid, body)
            t_applied = time.perf_counter()
            commit = self._commit(state)
            t_commit = time.perf_counter()
        except Exception:
            log.exception("applying a push to scene %s failed; reloading it from the database", state.id)
            self.forget(state.id)
            raise
        orphaned = state.orphans(only_nodes=removed) if removed else []
        restored = state.orphans(only_nodes=added) if added else []
        seconds = {"decode": t_decode - t0, "validate": t_validate - t_decode, "diff": t_diff - t_validate,
                   "blas": commit["blas_seconds"] + load_seconds[0],
                   "tlas": commit["tlas_seconds"] + (t_applied - t_apply - load_seconds[0]),
                   "commit": t_commit - t_applied}
        try:
            self._store(state, doc, old_tree, new, diff, seconds, changes)
        except Exception:
            self.forget(state.id)
            raise
        t_store = time.perf_counter()
        seconds["store"] = t_store - t_commit
        seconds["total"] = t_store - t0
        state.revision += 1
        state.length_unit = doc.length_unit
        state.last_commit = commit
        state.identity = identity
        state.live = None
        self.live.notify(state.id, state.revision)
        return self._answer(state, doc, diff, commit, seconds, orphaned, restored,
                            blas_reused=len(apply_stats.reused_geometries))

    def _store(self, state: SceneState, doc: DocumentPush, old: Tree, new: Tree, diff: TreeDiff,
               seconds: dict[str, float], identity_changes: IdentityChanges | None = None) -> None:
        summary = diff.summary()
        summary = {k: (len(v) if isinstance(v, list) else v) for k, v in summary.items()}
        summary["seconds"] = {k: round(v, 6) for k, v in seconds.items()}
        c = db.nodes.c
        with self.engine.begin() as conn:
            res = conn.execute(update(db.scenes).where(db.scenes.c.id == state.id)
                               .where(db.scenes.c.revision == state.revision)
                               .values(revision=state.revision + 1, length_unit=doc.length_unit,
                                       source=doc.source.model_dump() if doc.source else None))
            if res.rowcount != 1:
                current = conn.execute(select(db.scenes.c.revision).where(db.scenes.c.id == state.id)).scalar()
                raise Conflict(f"the scene changed under this push (now at revision {current})",
                               current_revision=current)
            gone = list(diff.removed) + [u for u in diff.upserts if u in old.index]
            for i in range(0, len(gone), 500):
                conn.execute(delete(db.nodes).where(c.scene_id == state.id).where(c.uuid.in_(gone[i:i + 500])))
            if diff.upserts:
                rows = []
                for u in diff.upserts:
                    j = new.index[u]
                    rows.append({"scene_id": state.id, "uuid": u, "position": float(j), "parent": new.parents[j],
                                 "name": new.names[j], "transform": _blob(new.local[j]),
                                 "geometry": new.geometries[j],
                                 "color": _color(new.colors[j])})
                conn.execute(insert(db.nodes), rows)
            if identity_changes is not None:
                _store_identity(conn, state.id, *identity_changes)
            conn.execute(insert(db.revisions).values(scene_id=state.id, revision=state.revision + 1, summary=summary))

    def _answer(self, state: SceneState, doc: DocumentPush, diff: TreeDiff, commit: dict, seconds: dict,
                orphaned: list, restored: list, blas_reused: int) -> dict[str, Any]:
        out: dict[str, Any] = {"scene": state.id, "revision": state.revision, "base_revision": doc.base_revision}
        out.update(diff.summary())
        out.update(blas_built=commit.get("blas_built", 0), blas_reused=blas_reused,
                   blas_loaded=commit.get("blas_loaded", 0),
                   instances=len(state.instances) + len(state.object_instances),
                   seconds=seconds, orphaned=orphaned, restored=restored,
                   reconciliation=doc.reconciliation.model_dump() if doc.reconciliation is not None else None,
                   dry_run=False)
        return out

    # ------------------------------------------------------------ assignments

    def _check_anchor(self, state: SceneState, node: str | None, what: str) -> None:
        if node is not None and not state.has_node(node):
            raise NotFound(f"{what}: no node {node} in scene {state.id} (revision {state.revision})", node=node)

    def _changed(self, state: SceneState) -> None:
        """After a stored assignment change (`_bump_assignments` counted it in the database)."""
        state.assign_revision += 1
        state.live = None
        self.live.notify(state.id, state.revision)

    @_retried
    def set_material(self, scene_id: str, key: str, body: dict) -> dict[str, Any]:
        material = material_adapter.validate_python(body)
        clean = material.model_dump(exclude_none=True)
        with self._current(scene_id) as state:
            if not state.has_node(key) and key not in state.objects:
                raise NotFound(f"no node or object {key} in scene {scene_id}", node=key)
            with self.engine.begin() as conn:
                self._bump_assignments(conn, state)
                conn.execute(delete(db.materials).where(db.materials.c.scene_id == scene_id)
                             .where(db.materials.c.node == key))
                conn.execute(insert(db.materials).values(scene_id=scene_id, node=key, body=clean))
            state.materials[key] = clean
            self._changed(state)
        return {"node": key, "material": clean, "orphaned": False}

    @_retried
    def delete_material(self, scene_id: str, key: str) -> None:
        with self._current(scene_id) as state:
            if key not in state.materials:
                raise NotFound(f"no material assigned to {key} in scene {scene_id}")
            with self.engine.begin() as conn:
                self._bump_assignments(conn, state)
                conn.execute(delete(db.materials).where(db.materials.c.scene_id == scene_id)
                             .where(db.materials.c.node == key))
            del state.materials[key]
            self._changed(state)

    def list_materials(self, scene_id: str) -> list[dict[str, Any]]:
        state = self.state(scene_id)
        with state.lock:
            return [{"node": k, "material": v, "orphaned": not state.has_node(k) and k not in state.objects}
                    for k, v in state.materials.items()]

    def _table(self, kind: str) -> tuple[Any, str]:
        return {"light": (db.lights, "lights"), "sensor": (db.sensors, "sensors"),
                "object": (db.sim_objects, "objects")}[kind]

    @_retried
    def add_assignment(self, scene_id: str, kind: str, body: dict) -> dict[str, Any]:
        """Add a light, sensor or sim-owned object (validated body); answers its public form."""
        body = dict(body)  # a retry (`_retried`) starts again from the body as given
        with self._current(scene_id) as state:
            anchor = state.anchor_of(body)
            self._check_anchor(state, anchor, kind)
            if kind == "light" and body["type"] == "goniometric":
                _validate_photometry(body["format"], body["data"])
            if kind == "object" and self.missing_geometries([body["geometry"]]):
                raise Invalid(f"geometry {body['geometry']} is not uploaded (PUT /geometries/{{id}} first)",
                              missing=[body["geometry"]])
            aid = str(uuidlib.uuid4())
            table, attr = self._table(kind)
            material = None
            if kind == "object":
                material = body.pop("material", None)
                try:
                    self._place_object(state, aid, body)
                    state.last_commit = self._commit(state)
                except Exception:
                    self.forget(scene_id)
                    raise
            with self.engine.begin() as conn:
                self._bump_assignments(conn, state)
                conn.execute(insert(table).values(id=aid, scene_id=scene_id, body=body))
                if kind == "object" and material is not None:
                    conn.execute(insert(db.materials).values(scene_id=scene_id, node=aid, body=material))
            getattr(state, attr)[aid] = body
            if kind == "object" and material is not None:
                state.materials[aid] = material
            self._changed(state)
            return {"id": aid, "body": body, "orphaned": False}

    def list_assignments(self, scene_id: str, kind: str) -> list[dict[str, Any]]:
        state = self.state(scene_id)
        _, attr = self._table(kind)
        with state.lock:
            out = []
            for aid, body in getattr(state, attr).items():
                anchor = state.anchor_of(body)
                out.append({"id": aid, "body": body, "orphaned": anchor is not None and not state.has_node(anchor)})
            return out

    def get_assignment(self, scene_id: str, kind: str, aid: str) -> dict[str, Any]:
        for item in self.list_assignments(scene_id, kind):
            if item["id"] == aid:
                return item
        raise NotFound(f"no {kind} {aid} in scene {scene_id}")

    @_retried
    def delete_assignment(self, scene_id: str, kind: str, aid: str) -> None:
        table, attr = self._table(kind)
        with self._current(scene_id) as state:
            items = getattr(state, attr)
            if aid not in items:
                raise NotFound(f"no {kind} {aid} in scene {scene_id}")
            if kind == "object":
                inst = state.object_instances.pop(aid, None)
                if inst is not None:
                    try:
                        state.tracer.remove_instance(inst)
                        state.last_commit = self._commit(state)
                    except Exception:
                        self.forget(scene_id)
                        raise
            with self.engine.begin() as conn:
                self._bump_assignments(conn, state)
                conn.execute(delete(table).where(table.c.id == aid))
                if kind == "object":
                    conn.execute(delete(db.materials).where(db.materials.c.scene_id == scene_id)
                                 .where(db.materials.c.node == aid))
            del items[aid]
            state.materials.pop(aid, None) if kind == "object" else None
            self._changed(state)

    def purge_orphans(self, scene_id: str) -> list[dict[str, str]]:
        """Delete every orphaned assignment of the scene; answers what was deleted."""
        with self._current(scene_id) as state:
            gone = state.orphans()
            for o in gone:
                if o["kind"] == "material":
                    self.delete_material(scene_id, o["id"])
                else:
                    self.delete_assignment(scene_id, o["kind"], o["id"])
            return gone

    # ------------------------------------------------------------ views

    def summary(self, scene_id: str) -> dict[str, Any]:
        state = self.state(scene_id)
        with state.lock:
            live = self._live_locked(state)
            n_instances = len(state.instances) + len(state.object_instances)
            triangles = 0
            counts: dict[str, int] = {}
            for u in state.instances:
                gid = str(state.tree.geometries[state.tree.index[u]])
                counts[gid] = counts.get(gid, 0) + 1
            for oid in state.object_instances:
                gid = state.objects[oid]["geometry"]
                counts[gid] = counts.get(gid, 0) + 1
            with self.engine.connect() as conn:
                source = conn.execute(select(db.scenes.c.source).where(db.scenes.c.id == state.id)).scalar()
                if counts:
                    tri = dict(conn.execute(select(db.geometries.c.id, db.geometries.c.n_triangles)
                                            .where(db.geometries.c.id.in_(list(counts)))).all())
                    triangles = sum(tri.get(g, 0) * k for g, k in counts.items())
            return {"id": state.id, "name": state.name, "revision": state.revision, "length_unit": state.length_unit,
                    "nodes": len(state.tree), "objects": n_instances, "triangles": triangles,
                    "geometries": len(counts), "effects": scene_effects(live, n_instances > len(live.materials)),
                    "orphaned": state.orphans(),
                    "materials_assigned": sum(1 for k in state.materials
                                              if state.has_node(k) or k in state.objects),
                    "default_material": dict(DEFAULT_MATERIAL),
                    "default_material_instances": n_instances - len(live.materials),
                    "lights": len(live.lights), "sensors": len(live.sensors), "sim_objects": len(state.objects),
                    "last_commit": state.last_commit, "source": source}

    def revisions(self, scene_id: str) -> list[dict[str, Any]]:
        """One entry per accepted push that changed the tree: its counts and stage seconds, oldest first."""
        self.state(scene_id)  # 404 for an unknown scene
        with self.engine.connect() as conn:
            rows = conn.execute(select(db.revisions).where(db.revisions.c.scene_id == scene_id)
                                .order_by(db.revisions.c.revision)).all()
        return [{"revision": r.revision, "created_at": r.created_at.isoformat() if r.created_at else None,
                 **r.summary} for r in rows]

    def nodes(self, scene_id: str) -> list[dict[str, Any]]:
        """The current tree, one record per node in document order: the pushed fields, the tracer
        instance, and what the CAD adapter reconciles a new document against — the occurrence
        ``path`` (`Tree.paths`), ``world`` (root_from_node, 16 numbers row-major, in the document's
        length unit) and the node's identity record (``product``, ``signature``; null without one)."""
        state = self.state(scene_id)
        with state.lock:
            t = state.tree
            paths = t.paths()
            local = t.local.reshape(-1, 16).tolist()
            if t.world_doc is not None:
                world_doc = t.world_doc
            else:  # the world in metres with its translations back in document units
                world_doc = t.world.copy()
                world_doc[:, :3, 3] /= t.scale
            world = world_doc.reshape(-1, 16).tolist()
            identity = state.identity
            out = []
            for i, u in enumerate(t.uuids):
                rec = identity.get(u)
                out.append({"uuid": u, "parent": t.parents[i], "name": t.names[i], "transform": local[i],
                            "geometry": t.geometries[i], "color": _color(t.colors[i]),
                            "instance": state.instances.get(u), "path": paths[i], "world": world[i],
                            "product": rec.product if rec is not None else None,
                            "signature": rec.signature.model_dump(exclude_none=True)
                            if rec is not None and rec.signature is not None else None})
            return out

    def live_scene(self, scene_id: str) -> LiveScene:
        state = self.state(scene_id)
        with state.lock:
            return self._live_locked(state)

    def _live_locked(self, state: SceneState) -> LiveScene:
        if state.live is not None:
            return state.live
        tree = state.tree
        node_world = {u: tree.world[i] for i, u in enumerate(tree.uuids)}
        # effective material per node: its own, else its parent's (rows visited parents first)
        effective: dict[str, dict] = {}
        if state.materials:
            for i in np.argsort(tree.depth, kind="stable"):
                u = tree.uuids[i]
                own = state.materials.get(u)
                if own is not None:
                    effective[u] = own
                else:
                    p = tree.parents[i]
                    if p is not None and p in effective:
                        effective[u] = effective[p]
        materials: dict[int, dict] = {}
        for u, inst in state.instances.items():
            if u in effective:
                materials[inst] = copy.deepcopy(effective[u])
        for oid, inst in state.object_instances.items():
            if oid in state.materials:
                materials[inst] = copy.deepcopy(state.materials[oid])
        instance_of_node = dict(state.instances)
        instance_of_node.update(state.object_instances)
        lights = []
        for lid, body in state.lights.items():
            resolved = self._resolve(state, lid, body)
            if resolved is not None:
                lights.append(resolved)
        sensors = []
        for sid, body in state.sensors.items():
            resolved = self._resolve(state, sid, body)
            if resolved is not None:
                sensors.append(resolved)
        state.live = LiveScene(state.id, state.revision, state.tracer, instance_of_node, node_world, materials,
                               dict(DEFAULT_MATERIAL), lights, sensors,
                               extras={"length_unit": state.length_unit, "objects": dict(state.objects)})
        return state.live

    def _resolve(self, state: SceneState, aid: str, body: dict) -> dict | None:
        """A light/sensor body in world metres (None while its node is missing)."""
        out = {k: copy.deepcopy(v) for k, v in body.items() if k not in ("attached_to", "name")}
        out["id"] = aid
        if body.get("type") == "area":
            node = body["node"]
            if not state.has_node(node):
                return None
            out.pop("node")
            out["instances"] = [state.instances[u] for u in state.tree.subtree(node) if u in state.instances]
            return out
        node = body.get("attached_to")
        if node is None:
            return out
        row = state.tree.index.get(node)
        if row is None:
            return None
        w = state.tree.world[row]
        lin = w[:3, :3]
        for key in ("position", "origin", "center"):
            if key in out:
                out[key] = (lin @ np.asarray(out[key], dtype=float) + w[:3, 3]).tolist()
        for key in ("direction", "normal", "up", "c0"):
            if key in out:
                d = lin @ np.asarray(out[key], dtype=float)
                out[key] = (d / np.linalg.norm(d)).tolist()
        for key in ("u", "v"):
            if key in out:
                out[key] = (lin @ np.asarray(out[key], dtype=float)).tolist()
        pol = out.get("polarization")
        if isinstance(pol, dict) and pol.get("type") == "linear":   # the field's axis turns with the node
            a = lin @ np.asarray(pol["axis"], dtype=float)
            out["polarization"] = {**pol, "axis": (a / np.linalg.norm(a)).tolist()}
        return out


IdentityChanges = tuple[dict[str, IdentityIn], list[str], bool]


def _identity_of(doc: DocumentPush, new: Tree) -> dict[str, IdentityIn]:
    """The push's identity records (uuid -> record); 422 if a key is not the uuid of a node of the pushed tree `new`."""
    if not doc.identity:
        return {}
    index = new.index
    unknown = [u for u in doc.identity if u not in index]
    if unknown:
        more = f" (and {len(unknown) - 1} more)" if len(unknown) > 1 else ""
        raise Invalid(f"identity: {unknown[0]} is not the uuid of a node in this push{more}", unknown=unknown[:100],
                      errors=[{"loc": ["identity", u], "msg": "not the uuid of a node in this push",
                               "type": "unknown_node"} for u in unknown[:100]])
    return doc.identity


def _identity_changes(old: dict[str, IdentityIn], new: dict[str, IdentityIn]) -> IdentityChanges | None:
    """What to write so that the stored records `old` become `new`: (records to insert, uuids whose rows
    to delete first, whether to delete every row of the scene instead), or None when they are equal.
    One pass over the records in memory (model equality: field values only); only changed records reach
    the database."""
    if not new:
        return ({}, [], True) if old else None
    write = {u: r for u, r in new.items() if old.get(u) != r}
    drop = [u for u in old if u not in new] + [u for u in write if u in old]
    if not write and not drop:
        return None
    return write, drop, False


def _store_identity(conn: Any, scene_id: str, write: dict[str, IdentityIn], drop: list[str], clear: bool) -> None:
    """Apply `_identity_changes` to the ``node_identity`` table on `conn` (inside the caller's transaction)."""
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


def _validate_photometry(fmt: str, text: str) -> None:
    """Parse a goniometric file with the tracer's parser (422 naming the problem if it is wrong)."""
    try:
        from tracer.photometry import parse_photometry
    except ImportError:  # the parser is not built yet: accept, it is parsed again at simulation time
        return
    try:
        parse_photometry(fmt, text)
    except ValueError as exc:
        raise Invalid(f"invalid {fmt} photometry file: {exc}") from exc


def scene_effects(live: LiveScene, uses_default: bool = True) -> list[str]:
    """The scene's effect set, by the transport's one rule (`tracer.effects.derive_effects`) over its
    materials (and the default material where some instance uses it) and its lights. A body stored under older, looser
    rules that the tracer now refuses is left out here (a summary never fails); a query says what is wrong."""
    from tracer.effects import derive_effects
    from tracer.optics.surfaces.dispatch import MaterialError, material_spec

    specs = []
    for body in list(live.materials.values()) + ([live.default_material] if uses_default else []):
        try:
            specs.append(material_spec(body))
        except MaterialError:
            continue
    return derive_effects(specs, live.lights)


def validate_body(kind: str, body: Any) -> dict:
    """Validate a light, sensor or object body; answers it as a clean dict (422 on a bad field)."""
    adapter = {"light": light_adapter, "sensor": sensor_adapter}.get(kind)
    model = adapter.validate_python(body) if adapter is not None else ObjectCreate.model_validate(body)
    out = model.model_dump(exclude_none=True)
    if kind == "object":
        out["transform"] = [float(x) for x in out["transform"]]
        t = np.asarray(out["transform"]).reshape(4, 4)
        try:
            Tree.build(["00000000-0000-0000-0000-000000000000"], [None], [""], t.reshape(1, 16), [None], None, "m")
        except TreeError as exc:
            raise Invalid(f"object transform: {str(exc).split(': ', 1)[-1]}") from exc
    for key in ("position", "origin", "center", "direction", "normal", "u", "v", "up"):
        if key in out:
            out[key] = list(out[key])
    return out
