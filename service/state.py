"""The sync service's core, one object the routes hold: `SceneManager`, made of four parts with one job each,
along the lines of the FastAPI full-stack template (storage apart from the domain logic):

| part | module | does |
| --- | --- | --- |
| storage | `service.store.SceneStore` | every SQL statement; guarded writes (`Raced`, 409) |
| live scenes | `service.scenes.Scenes` | scenes in memory, current with the database; geometries; views |
| pushes | `service.push.Pushes` | a pushed tree decoded, diffed, applied to the tracer scene, stored |
| assignments | `service.assignments.Assignments` | materials, lights, sensors, sim objects by node uuid |

`SceneManager` wires them together and answers the routes' calls by handing each to its part; it holds no
logic of its own. Domain errors are raised as `service.errors` exceptions; the routes stay thin.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from sqlalchemy import Engine

from service.assignments import Assignments, validate_body
from service.config import Settings
from service.live import scene_effects
from service.meshes import MeshStore
from service.push import Pushes
from service.scenes import DEFAULT_MATERIAL, Scenes, SceneState
from service.store import SceneStore

__all__ = ["DEFAULT_MATERIAL", "SceneManager", "SceneState", "scene_effects", "validate_body"]


class SceneManager:
    """All scenes of this process, backed by the database and the mesh store (see the module docstring)."""

    def __init__(self, settings: Settings, engine: Engine, meshes: MeshStore,
                 scene_factory: Callable[[], Any] | None = None) -> None:
        self.settings = settings
        self.engine = engine
        self.meshes = meshes
        self.store = SceneStore(engine)
        self.scenes = Scenes(settings, self.store, meshes, scene_factory)
        self.pushes = Pushes(settings, self.scenes)
        self.assignments = Assignments(self.scenes)
        self.live = self.scenes.live
        # scenes
        self.list_scenes = self.store.list_scenes
        self.create_scene = self.store.create_scene
        self.delete_scene = self.scenes.delete
        self.revision = self.scenes.revision
        self.state = self.scenes.state
        self.forget = self.scenes.forget
        # geometries
        self.known_geometries = self.scenes.known
        self.missing_geometries = self.scenes.missing_geometries
        self.put_geometry = self.scenes.put_geometry
        self.geometry_glb = self.scenes.geometry_glb
        # pushes
        self.push = self.pushes.push
        # assignments
        self.set_material = self.assignments.set_material
        self.delete_material = self.assignments.delete_material
        self.list_materials = self.assignments.list_materials
        self.add_assignment = self.assignments.add_assignment
        self.list_assignments = self.assignments.list_assignments
        self.get_assignment = self.assignments.get_assignment
        self.delete_assignment = self.assignments.delete_assignment
        self.purge_orphans = self.assignments.purge_orphans
        # views
        self.summary = self.scenes.summary
        self.revisions = self.scenes.revisions
        self.nodes = self.scenes.nodes
        self.removed_nodes = self.scenes.removed_nodes
        self.live_scene = self.scenes.live_scene
