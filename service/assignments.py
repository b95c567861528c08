"""Assignments: materials, lights, sensors and simulation-owned objects, by node uuid, kept across pushes.

Each change validates its body, runs under the scene's lock on the scene as the database holds it now
(`Scenes.current`), and is written in one transaction guarded by the scene's ``(revision, assign_revision)``
(`SceneStore`); when another service process changed the scene in between (`Raced`), the scene is reloaded
and the change tried again on it (`_retried`), 409 after `RACE_TRIES` tries. An assignment whose node a push
removed stays, orphaned, and comes back with the node.
"""

from __future__ import annotations

import functools
import uuid as uuidlib
from collections.abc import Callable
from typing import Any

import numpy as np
from pydantic import BaseModel, TypeAdapter

from service import kind_wire
from service.elements import check_assignment, check_support
from service.elements import public as element_public
from service.elements import sync as element_sync
from service.errors import Conflict, Invalid, NotFound
from service.scenes import Scenes, SceneState
from service.schemas import Light, Material, ObjectCreate, Sensor
from service.store import TABLES, Raced
from service.tree import Tree, TreeError
from tracer.optics.fields import node_field

material_adapter: TypeAdapter = TypeAdapter(Material)
light_adapter: TypeAdapter = TypeAdapter(Light)
sensor_adapter: TypeAdapter = TypeAdapter(Sensor)

RACE_TRIES = 3


def _retried(method: Callable[..., Any]) -> Callable[..., Any]:
    """Run an assignment change again on the reloaded scene when another process changed the scene between
    this one's check and its guarded write; 409 after `RACE_TRIES` tries."""

    @functools.wraps(method)
    def run(self: Assignments, scene_id: str, *args: Any, **kwargs: Any) -> Any:
        for _ in range(RACE_TRIES):
            try:
                return method(self, scene_id, *args, **kwargs)
            except Raced:
                self.scenes.forget(scene_id)   # memory may be ahead of the database (an object placed): reload it
        raise Conflict(f"scene {scene_id} kept changing through other service processes during this change "
                       f"({RACE_TRIES} tries); nothing was changed, try again")

    return run


class Assignments:
    """What users assign in the simulation, on the scenes of `scenes`."""

    def __init__(self, scenes: Scenes) -> None:
        self.scenes = scenes
        self.store = scenes.store

    @staticmethod
    def _check_anchor(state: SceneState, node: str | None, what: str) -> None:
        if node is not None and not state.has_node(node):
            raise NotFound(f"{what}: no node {node} in scene {state.id} (revision {state.revision})", node=node)

    # ------------------------------------------------------------ materials

    @_retried
    def set_material(self, scene_id: str, key: str, body: dict | BaseModel) -> dict[str, Any]:
        """Assign a material body: a dict (validated here) or a `Material` the route already validated (not again)."""
        model = body if isinstance(body, BaseModel) else material_adapter.validate_python(body)
        clean = model.model_dump(exclude_none=True)
        with self.scenes.current(scene_id) as state:
            if not state.has_node(key) and key not in state.objects:
                raise NotFound(f"no node or object {key} in scene {scene_id}", node=key)
            self.store.set_material(scene_id, state.version, key, clean)
            state.materials[key] = clean
            self._retabulate(state)
            self.scenes.changed(state)
        return {"node": key, "material": clean, "orphaned": False}

    @_retried
    def delete_material(self, scene_id: str, key: str) -> None:
        with self.scenes.current(scene_id) as state:
            if key not in state.materials:
                raise NotFound(f"no material assigned to {key} in scene {scene_id}")
            self.store.delete_material(scene_id, state.version, key)
            del state.materials[key]
            self._retabulate(state)
            self.scenes.changed(state)

    def _retabulate(self, state: SceneState) -> None:
        """After a material change: elements used through their tabulated BSDF follow their part's ior (a table
        for the new one, or not applied, saying why, where the part is no dielectric any more)."""
        if any(b.get("model") == "bsdf" for b in state.elements.values()):
            try:
                element_sync(state, self.scenes.elements)
                state.last_commit = self.scenes.commit(state)
            except Exception:
                self.scenes.forget(state.id)
                raise

    def list_materials(self, scene_id: str) -> list[dict[str, Any]]:
        state = self.scenes.state(scene_id)
        with state.lock:
            return [{"node": k, "material": v, "orphaned": not state.has_node(k) and k not in state.objects}
                    for k, v in state.materials.items()]

    # ------------------------------------------------------------ lights, sensors, objects

    @_retried
    def add_assignment(self, scene_id: str, kind: str, body: dict) -> dict[str, Any]:
        """Add a light, sensor or sim-owned object (validated body); answers its public form."""
        body = dict(body)  # a retry (`_retried`) starts again from the body as given
        with self.scenes.current(scene_id) as state:
            self._check_anchor(state, state.anchor_of(kind, body), kind)
            field = node_field(kind_wire.fields_of(kind, body)) if kind == "sensor" else None
            if field is not None and not any(u in state.instances for u in state.tree.subtree(body[field])):
                raise Invalid(f"{body['type']} sensor: node {body[field]} and its descendants have no geometry: "
                              f"nothing to tally", node=body[field])
            if kind == "light" and (body.get("facing") is not None or body.get("faces") is not None):
                _check_chosen_faces(state, body)
            if kind == "object" and self.scenes.missing_geometries([body["geometry"]]):
                raise Invalid(f"geometry {body['geometry']} is not uploaded (PUT /geometries/{{id}} first)",
                              missing=[body["geometry"]])
            aid = str(uuidlib.uuid4())
            material = None
            if kind == "object":
                material = body.pop("material", None)
                try:
                    self.scenes.place_object(state, aid, body)
                    state.last_commit = self.scenes.commit(state)
                except Exception:
                    self.scenes.forget(scene_id)
                    raise
            self.store.add_assignment(scene_id, state.version, kind, aid, body, material)
            getattr(state, TABLES[kind][1])[aid] = body
            if material is not None:
                state.materials[aid] = material
            self.scenes.changed(state)
            return {"id": aid, "body": body, "orphaned": False}

    def list_assignments(self, scene_id: str, kind: str) -> list[dict[str, Any]]:
        state = self.scenes.state(scene_id)
        with state.lock:
            out = []
            for aid, body in getattr(state, TABLES[kind][1]).items():
                anchor = state.anchor_of(kind, body)
                out.append({"id": aid, "body": body, "orphaned": anchor is not None and not state.has_node(anchor)})
            return out

    def get_assignment(self, scene_id: str, kind: str, aid: str) -> dict[str, Any]:
        for item in self.list_assignments(scene_id, kind):
            if item["id"] == aid:
                return item
        raise NotFound(f"no {kind} {aid} in scene {scene_id}")

    @_retried
    def delete_assignment(self, scene_id: str, kind: str, aid: str) -> None:
        with self.scenes.current(scene_id) as state:
            items = getattr(state, TABLES[kind][1])
            if aid not in items:
                raise NotFound(f"no {kind} {aid} in scene {scene_id}")
            if kind == "object":
                inst = state.object_instances.pop(aid, None)
                if inst is not None:
                    try:
                        state.tracer.remove_instance(inst)
                        state.last_commit = self.scenes.commit(state)
                    except Exception:
                        self.scenes.forget(scene_id)
                        raise
            self.store.delete_assignment(scene_id, state.version, kind, aid)
            del items[aid]
            if kind == "object":
                state.materials.pop(aid, None)
            self.scenes.changed(state)

    # ------------------------------------------------------------ elements with an inside

    @_retried
    def add_element(self, scene_id: str, body: dict) -> dict[str, Any]:
        """Put a library element onto a node's support faces (`service.elements`); 422 where it cannot go (checked
        first), 409 where its support shares a triangle with another element's on the node, with nothing changed."""
        body = dict(body)
        with self.scenes.current(scene_id) as state:
            check_assignment(body, self.scenes.elements, state)
            check_support(body, state)   # a bad body is its 422 whether or not the node carries an element already
            aid = str(uuidlib.uuid4())
            state.elements[aid] = body
            try:
                element_sync(state, self.scenes.elements)
            except Exception:
                self.scenes.forget(scene_id)
                raise
            problem = state.element_problems.pop(aid, None)
            taken = state.element_taken.pop(aid, None)
            if problem is not None:   # the tracer refused it before changing anything
                del state.elements[aid]
                if taken is not None:
                    raise Conflict(f"node {body['node']} already carries element assignment {taken} on some of these "
                                   f"faces: one element a face; select other faces, or delete {taken} first",
                                   node=body["node"], assignment=taken)
                raise Invalid(f"the element cannot go onto node {body['node']}: {problem}", node=body["node"])
            try:
                state.last_commit = self.scenes.commit(state)
                self.store.add_assignment(scene_id, state.version, "element", aid, body)
            except Exception:
                self.scenes.forget(scene_id)
                raise
            self.scenes.changed(state)
            return element_public(state, aid, body)

    def list_elements(self, scene_id: str) -> list[dict[str, Any]]:
        state = self.scenes.state(scene_id)
        with state.lock:
            return [element_public(state, aid, body) for aid, body in state.elements.items()]

    def get_element(self, scene_id: str, aid: str) -> dict[str, Any]:
        state = self.scenes.state(scene_id)
        with state.lock:
            if aid not in state.elements:
                raise NotFound(f"no element assignment {aid} in scene {scene_id}")
            return element_public(state, aid, state.elements[aid])

    @_retried
    def switch_element(self, scene_id: str, aid: str, element: str) -> dict[str, Any]:
        """The element assignment `aid` carries library element `element` from now on (a packed pattern in place of
        the one it was packed from): the same node and faces, one element's inner model changed. 422 for an element
        the library lacks or that cannot go onto the faces, with nothing changed."""
        with self.scenes.current(scene_id) as state:
            if aid not in state.elements:
                raise NotFound(f"no element assignment {aid} in scene {scene_id}")
            old = state.elements[aid]
            body = {**old, "element": element}
            check_assignment(body, self.scenes.elements, state)
            if old["element"] == element:
                return element_public(state, aid, old)
            state.elements[aid] = body
            state.element_instances.pop(aid, None)   # put on again, with the new model
            try:
                element_sync(state, self.scenes.elements)
                problem = state.element_problems.get(aid)
                if problem is not None:
                    state.elements[aid] = old
                    state.element_problems.pop(aid, None)
                    element_sync(state, self.scenes.elements)
                    raise Invalid(f"element: it cannot go onto node {body['node']}: {problem}", node=body["node"])
                state.last_commit = self.scenes.commit(state)
                self.store.replace_assignment(scene_id, state.version, "element", aid, body)
            except Invalid:
                state.last_commit = self.scenes.commit(state)
                raise
            except Exception:
                self.scenes.forget(scene_id)
                raise
            self.scenes.changed(state)
            return element_public(state, aid, body)

    @_retried
    def delete_element(self, scene_id: str, aid: str) -> None:
        """Take an element off its part (its support is the part's own faces again; the part keeps its instance,
        material and any other element it carries)."""
        with self.scenes.current(scene_id) as state:
            if aid not in state.elements:
                raise NotFound(f"no element assignment {aid} in scene {scene_id}")
            try:
                del state.elements[aid]
                element_sync(state, self.scenes.elements)
                state.last_commit = self.scenes.commit(state)
                self.store.delete_assignment(scene_id, state.version, "element", aid)
            except Exception:
                self.scenes.forget(scene_id)
                raise
            self.scenes.changed(state)

    def purge_orphans(self, scene_id: str) -> list[dict[str, str]]:
        """Delete every orphaned assignment of the scene; answers what was deleted."""
        with self.scenes.current(scene_id) as state:
            gone = state.orphans()
            for o in gone:
                if o["kind"] == "material":
                    self.delete_material(scene_id, o["id"])
                elif o["kind"] == "element":
                    self.delete_element(scene_id, o["id"])
                else:
                    self.delete_assignment(scene_id, o["kind"], o["id"])
            return gone


def validate_body(kind: str, body: Any) -> dict:
    """Validate a light, sensor or object body; answers it as a clean dict (422 on a bad field).

    A wire model (`Light`, `Sensor`, `ObjectCreate`) that FastAPI already validated is not validated again (pydantic
    would run every validator anew); only what the schema cannot say (an object's transform) is checked here."""
    adapter = {"light": light_adapter, "sensor": sensor_adapter}.get(kind)
    if isinstance(body, BaseModel):
        model = body
    else:
        model = adapter.validate_python(body) if adapter is not None else ObjectCreate.model_validate(body)
    out = model.model_dump(exclude_none=True)
    if kind == "object":
        out["transform"] = [float(x) for x in out["transform"]]
        t = np.asarray(out["transform"]).reshape(4, 4)
        try:
            Tree.build(["00000000-0000-0000-0000-000000000000"], [None], [""], t.reshape(1, 16), [None], None, "m")
        except TreeError as exc:
            raise Invalid(f"object transform: {str(exc).split(': ', 1)[-1]}") from exc
    return {k: list(v) if isinstance(v, tuple) else v for k, v in out.items()}   # [x, y, z] as JSON keeps it


def _check_chosen_faces(state: SceneState, body: dict) -> None:
    """422 for an area light whose `facing` no triangle of its node's subtree faces, or whose `faces` its parts'
    meshes do not have (`tracer.optics.lights.area`), before anything is stored; a node without geometry yet is left
    to the query, which names it."""
    from tracer.errors import TracerError
    from tracer.optics.lights import pack_lights

    field = node_field(kind_wire.fields_of("light", body))
    node = body.get(field) if field is not None else None
    if node is None or not state.has_node(node):
        return
    instances = [state.instances[u] for u in state.tree.subtree(node) if u in state.instances]
    if not instances:
        return
    light = {k: v for k, v in body.items() if k not in ("attached_to", "name", field)}
    try:
        pack_lights([{**light, "instances": instances}], state.tracer)
    except TracerError as exc:
        raise Invalid(f"light: {exc}", field="faces" if "faces" in body else "facing") from None
