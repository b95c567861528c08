"""Read-only views of a scene for the routes: its summary, its revisions, its nodes. A part of
`service.scenes.Scenes`, which holds the scenes' states and the database.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from service.live import DEFAULT_MATERIAL, scene_effects
from service.store import color_of

if TYPE_CHECKING:
    from service.live import LiveScene
    from service.store import SceneStore


class SceneViews:
    """What `GET /scenes/{id}`, `GET /scenes/{id}/revisions` and `GET /scenes/{id}/nodes` answer."""

    store: SceneStore

    def state(self, scene_id: str) -> Any:
        """The scene's state, current with the database (`service.scenes.Scenes.state` provides it)."""
        raise NotImplementedError

    def live_locked(self, state: Any) -> LiveScene:
        """The scene's live snapshot, its lock held (`service.scenes.Scenes.live_locked` provides it)."""
        raise NotImplementedError

    def summary(self, scene_id: str) -> dict[str, Any]:
        state = self.state(scene_id)
        with state.lock:
            live = self.live_locked(state)
            n_instances = len(state.instances) + len(state.object_instances)
            counts: dict[str, int] = {}
            for u in state.instances:
                gid = str(state.tree.geometries[state.tree.index[u]])
                counts[gid] = counts.get(gid, 0) + 1
            for oid in state.object_instances:
                gid = state.objects[oid]["geometry"]
                counts[gid] = counts.get(gid, 0) + 1
            source = self.store.source(state.id)
            triangles = self.store.triangles(counts)
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
        return self.store.revisions(scene_id)

    def removed_nodes(self, scene_id: str) -> list[dict[str, Any]]:
        """The nodes pushes removed that the scene still remembers (oldest removal first): the records
        ``nodes`` gave for them then (``path``, ``product``, ``signature``, ``transform``, ``world``,
        ``geometry``…), with ``removed_revision``, ``removed_at``, ``length_unit`` and the ``assignments``
        they carried (still kept, orphaned: they come back with the node's UUID)."""
        state = self.state(scene_id)
        with state.lock:
            return [dict(r) for r in state.removed.values()]

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
                            "geometry": t.geometries[i], "color": color_of(t.colors[i]),
                            "instance": state.instances.get(u), "path": paths[i], "world": world[i],
                            "product": rec.product if rec is not None else None,
                            "signature": rec.signature.model_dump(exclude_none=True)
                            if rec is not None and rec.signature is not None else None})
            return out
