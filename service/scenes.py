"""Live scenes: every scene of this process in memory, current with the database, and the views of them.

`Scenes` owns, per scene, a `SceneState`: the current `Tree`, the committed `tracer.Scene`, the instance id of
every node with geometry and every assignment (materials, lights, sensors, sim-owned objects, keyed by uuid).
A scene is loaded on first use (tree, identity records, assignments, and a tracer scene whose bottom levels
come from the BLAS cache under the data directory: none rebuilt if intact).

Several service processes may share one database (and one data directory: the mesh store and the BLAS cache).
Every use of a scene (`state`) compares ``(revision, assign_revision)`` in the database with the scene in
memory (one SELECT of one row) and catches up when the database is ahead: a newer revision reloads the scene
as after a restart; a newer ``assign_revision`` (another process changed an assignment or only identity
records) reloads those tables in place and moves sim objects' instances. Listeners (`LiveRegistry`) hear of
it as of any change.

The views (`summary`, `nodes`, `live_scene`: the snapshot a simulation reads) are built here too, under the
scene's lock. Pushes (`service.push`) and assignments (`service.assignments`) change scenes through this
class; SQL lives in `service.store`.
"""

from __future__ import annotations

import contextlib
import copy
import logging
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from service import kind_wire
from service.config import Settings
from service.document import NodeBytes
from service.elements import ElementLibrary
from service.elements import describe as element_describe
from service.elements import sync as element_sync
from service.errors import NotFound
from service.live import DEFAULT_MATERIAL, DELETED, LiveRegistry, LiveScene
from service.meshes import MeshStore
from service.scene_geometries import SceneGeometries
from service.scene_views import SceneViews
from service.schemas import LENGTH_UNITS, IdentityIn
from service.store import SceneStore, normalize_positions
from service.tree import Tree, apply_to_scene, diff_trees

log = logging.getLogger("lumenlink.service")



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
    face_ids: dict[str, Any] = field(default_factory=dict)  # geometry id -> its triangles' B-rep face indices
    materials: dict[str, dict] = field(default_factory=dict)  # node uuid / object id -> material body
    lights: dict[str, dict] = field(default_factory=dict)  # id -> body as given
    sensors: dict[str, dict] = field(default_factory=dict)
    objects: dict[str, dict] = field(default_factory=dict)
    elements: dict[str, dict] = field(default_factory=dict)  # element assignment id -> body
    element_instances: dict[str, int] = field(default_factory=dict)  # element assignment id -> instance carrying it
    element_problems: dict[str, str] = field(default_factory=dict)  # element assignment id -> why it is not applied
    element_taken: dict[str, str] = field(default_factory=dict)  # ... -> the assignment whose support it overlaps
    element_ior: dict[str, Any] = field(default_factory=dict)  # element assignment id -> its BSDF table's ior
    element_model_error: dict[str, Any] = field(default_factory=dict)  # ... -> its BSDF table's measured error
    last_commit: dict[str, Any] = field(default_factory=dict)
    node_bytes: NodeBytes | None = None  # where each node sits in the body that made `tree` (row i = chunk i)
    identity: dict[str, IdentityIn] = field(default_factory=dict)  # node uuid -> its identity record, as stored
    removed: dict[str, dict] = field(default_factory=dict)  # uuid -> what the node was (service.push), oldest first
    live: LiveScene | None = None
    lock: threading.RLock = field(default_factory=threading.RLock)

    @property
    def version(self) -> tuple[int, int]:
        """``(revision, assign_revision)``: what the database must still hold for a change to be written."""
        return self.revision, self.assign_revision

    # ------------------------------------------------------------ references to nodes

    def has_node(self, key: str) -> bool:
        return key in self.tree.index

    def anchor_of(self, kind: str, body: dict) -> str | None:
        """The node a light/sensor/object body depends on (attached_to, or an area light's node)."""
        return kind_wire.anchor_of(kind, body)

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
        for kind, table in (("light", self.lights), ("sensor", self.sensors), ("object", self.objects),
                            ("element", self.elements)):
            for aid, body in table.items():
                node = body["node"] if kind == "element" else self.anchor_of(kind, body)
                if missing(node):
                    out.append({"kind": kind, "id": aid, "node": node})  # type: ignore[dict-item]
        return out


class Scenes(SceneGeometries, SceneViews):
    """All scenes of this process, backed by the database (`SceneStore`) and the mesh store."""

    def __init__(self, settings: Settings, store: SceneStore, meshes: MeshStore,
                 scene_factory: Callable[[], Any] | None = None) -> None:
        self.settings = settings
        self.store = store
        self.meshes = meshes
        self._scene_factory = scene_factory
        self._states: dict[str, SceneState] = {}
        self._lock = threading.Lock()
        self._scene_locks: dict[str, threading.RLock] = {}
        # the scene's lock is the one its state holds (`_load` gives it): taking it reads nothing from the database,
        # so a query reads the scene's state once, in `live_scene`
        self.live = LiveRegistry(self.live_scene, self.revision, self.scene_lock)
        self.known_geometries: set[str] = store.geometry_ids()
        self.elements = ElementLibrary(store.engine, settings.data_dir / "elements", meshes)   # shared by all scenes

    def new_tracer_scene(self) -> Any:
        if self._scene_factory is not None:
            return self._scene_factory()
        import tracer  # imported on first use: numba start-up is not paid by /health

        cache = self.settings.blas_dir
        cache.mkdir(parents=True, exist_ok=True)
        return tracer.Scene(cache_dir=cache)

    # ------------------------------------------------------------ scenes current with the database

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
        if state is not None and self.store.version(scene_id) == state.version:
            return state
        lock = self.scene_lock(scene_id)
        with lock:
            state = self._states.get(scene_id)
            if state is None:
                state = self._load(scene_id, lock)
                with self._lock:
                    self._states[scene_id] = state
                return state
            version = self.store.version(scene_id)
            if version == state.version:  # a change by this process, done meanwhile
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
    def current(self, scene_id: str) -> Iterator[SceneState]:
        """The scene's lock held, and the scene brought up to date under it (for a change)."""
        with self.scene_lock(scene_id):
            yield self.state(scene_id)

    def scene_lock(self, scene_id: str) -> threading.RLock:
        with self._lock:
            return self._scene_locks.setdefault(scene_id, threading.RLock())

    def forget(self, scene_id: str) -> None:
        """Drop the in-memory scene; the next use reloads it from the database."""
        with self._lock:
            self._states.pop(scene_id, None)

    def delete(self, scene_id: str) -> None:
        """Delete a scene from the database and memory; its results go stale and its jobs are cancelled."""
        with self.current(scene_id):
            self.store.delete_scene(scene_id)
            self.forget(scene_id)
            self.live.notify(scene_id, DELETED)

    def changed(self, state: SceneState) -> None:
        """After a stored change that keeps the revision (the store counted it in ``assign_revision``)."""
        state.assign_revision += 1
        state.live = None
        self.live.notify(state.id, state.revision)

    def _load(self, scene_id: str, lock: threading.RLock) -> SceneState:
        read = self.store.read_scene(scene_id)
        if read is None:
            raise NotFound(f"no scene {scene_id}")
        row, node_rows, stored = read
        normalize_positions(self.store.engine, scene_id, node_rows)
        unit = row.length_unit or "m"
        transforms = (np.frombuffer(b"".join(r.transform for r in node_rows), dtype="<f8").reshape(-1, 16)
                      if node_rows else np.zeros((0, 16)))
        tree = Tree.build([r.uuid for r in node_rows], [r.parent for r in node_rows], [r.name for r in node_rows],
                          transforms, [r.geometry for r in node_rows],
                          [tuple(r.color) if r.color is not None else None for r in node_rows], unit)
        state = SceneState(scene_id, row.name, row.revision, row.length_unit, Tree.empty(unit),
                           self.new_tracer_scene(), assign_revision=row.assign_revision,
                           materials=stored["materials"], lights=stored["lights"], sensors=stored["sensors"],
                           objects=stored["objects"], elements=stored["elements"], lock=lock,
                           identity=stored["identity"], removed=stored.get("removed") or {})
        diff = diff_trees(state.tree, tree)
        state.tree = tree
        apply_to_scene(state.tracer, state.instances, tree, diff, lambda g: self.ensure_geometry(state, g))
        for oid, body in state.objects.items():
            self.place_object(state, oid, body)
        element_sync(state, self.elements)
        state.last_commit = self.commit(state)
        log.info("loaded scene %s (revision %d, %d nodes): %s", scene_id, state.revision, len(tree),
                 state.last_commit)
        return state

    def rebuilt(self, scene_id: str) -> SceneState:
        """A scene of its own, rebuilt from the database as a restart would (its tracer scene built anew, its
        elements applied, committed), that nobody else sees or changes: a pack changes its element freely."""
        if self.store.version(scene_id) is None:
            raise NotFound(f"no scene {scene_id}")
        return self._load(scene_id, threading.RLock())

    def _reload_assignments(self, state: SceneState) -> None:
        """Bring the assignments and identity records of `state` (tree unchanged) up to the database's, in place:
        sim objects gone or new get their instances removed or added (one top-level commit if any did)."""
        assign_revision, stored = self.store.read_assignments(state.id)
        moved = False
        for oid, body in state.objects.items():
            if stored["objects"].get(oid) != body:
                inst = state.object_instances.pop(oid, None)
                if inst is not None:
                    state.tracer.remove_instance(inst)
                    moved = True
        for oid, body in stored["objects"].items():
            if oid not in state.object_instances:
                self.place_object(state, oid, body)
                moved = moved or oid in state.object_instances
        if stored["elements"] != state.elements:
            state.elements = stored["elements"]
            element_sync(state, self.elements)
            moved = True
        if moved:
            state.last_commit = self.commit(state)
        state.materials, state.lights, state.sensors = stored["materials"], stored["lights"], stored["sensors"]
        state.objects, state.identity = stored["objects"], stored["identity"]
        state.assign_revision = assign_revision
        state.live = None

    # ------------------------------------------------------------ geometry

    @staticmethod
    def commit(state: SceneState) -> dict[str, Any]:
        stats = state.tracer.commit()
        return {"blas_built": int(getattr(stats, "blas_built", 0)),
                "blas_loaded": int(getattr(stats, "blas_loaded", 0)),
                "blas_seconds": float(getattr(stats, "blas_seconds", 0.0)),
                "tlas_seconds": float(getattr(stats, "tlas_seconds", 0.0))}

    # ------------------------------------------------------------ sim-owned objects in the tracer scene

    @staticmethod
    def _object_transform(state: SceneState, body: dict) -> np.ndarray | None:
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

    def place_object(self, state: SceneState, oid: str, body: dict) -> None:
        """Add, move or remove the object's instance so it matches the tree (call before commit)."""
        t = self._object_transform(state, body)
        inst = state.object_instances.get(oid)
        if t is None:
            if inst is not None:
                state.tracer.remove_instance(inst)
                del state.object_instances[oid]
            return
        if inst is None:
            self.ensure_geometry(state, body["geometry"])
            state.object_instances[oid] = state.tracer.add_instance(body["geometry"], t)
        else:
            state.tracer.set_transform(inst, t)

    def live_scene(self, scene_id: str) -> LiveScene:
        state = self.state(scene_id)
        with state.lock:
            return self.live_locked(state)

    def live_locked(self, state: SceneState) -> LiveScene:
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
        lights = [r for r in (_resolve(state, "light", i, body) for i, body in state.lights.items()) if r is not None]
        sensors = [r for r in (_resolve(state, "sensor", i, body) for i, body in state.sensors.items())
                   if r is not None]
        state.live = LiveScene(state.id, state.revision, state.tracer, instance_of_node, node_world, materials,
                               dict(DEFAULT_MATERIAL), lights, sensors,
                               extras={"length_unit": state.length_unit, "objects": dict(state.objects),
                                       "elements": element_describe(state)})
        return state.live


def _resolve(state: SceneState, family: str, aid: str, body: dict) -> dict | None:
    """A light/sensor body in world metres (None while its node is missing); a body with a node field (an area
    light, a surface sensor) carries "instances": the instance ids of that node's subtree (`kind_wire.follow_node`)."""
    node = kind_wire.anchor_of(family, body)
    world, instances = None, None
    if node is not None:
        if not state.has_node(node):
            return None
        if body.get("attached_to") is not None:
            world = state.tree.world[state.tree.index[node]]
        else:
            instances = [state.instances[u] for u in state.tree.subtree(node) if u in state.instances]
    return {**kind_wire.follow_node(family, body, world, instances), "id": aid}
