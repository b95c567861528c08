"""Assignments by UUID: materials, lights, sensors and simulation-owned objects of a scene.

They refer to document nodes by uuid and survive every push (a node may be named by its path instead,
`service.paths`: it is resolved to the node's uuid when the call is made, and the uuid is stored); when a push
removes their node they are *orphaned* (kept, listed, inactive) and live again if the uuid returns. ``DELETE``
purges one; ``DELETE /scenes/{id}/orphans`` purges every orphan of the scene.
"""


from typing import Any

from fastapi import APIRouter, Request, Response
from pydantic import Field

from service import kind_wire, paths, units
from service.errors import ServiceError
from service.routes.deps import ItemId, Manager, NodeRef, SceneId
from service.schemas import AssignmentPublic, Light, Material, MaterialPublic, ObjectCreate, OrphanPublic, Sensor
from service.state import validate_body
from tracer.optics.fields import node_field

router = APIRouter(tags=["assignments"])


class AssignmentAdded(AssignmentPublic):
    """A light, sensor or object just added, with what looks wrong about it."""

    warnings: list[str] = Field(default_factory=list, description=(
        "A light or sensor far outside the model (more than 100 diagonals of its box): positions are world metres, "
        "whatever the document's length unit (the message names it). Added all the same."))


def _far(request: Request, scene_id: str, kind: str, item_id: str) -> list[str]:
    """Warnings for a light or sensor just added that lies far outside the model (`service.units`)."""
    try:
        live = request.app.state.live.get(scene_id)
    except ServiceError:   # a scene the simulation cannot read yet: nothing to measure against
        return []
    where = units.light_positions if kind == "light" else units.sensor_positions
    return units.far_warnings(live, where(live, [item_id]))


def _node_key(manager: Manager, scene_id: str, ref: str) -> str:
    """A node (or object) reference as the key assignments are stored under: a UUID as it is, a path resolved."""
    if paths.is_uuid(ref):
        return ref.lower()
    return paths.resolve(manager.nodes(scene_id), ref, scene_id)


def _resolve_anchors(manager: Manager, scene_id: str, kind: str, body: dict[str, Any]) -> dict[str, Any]:
    """The body with a path in `attached_to` (or in its kind's node field: an area light's or a surface sensor's
    `node`) replaced by that node's uuid."""
    keys = ["attached_to", node_field(kind_wire.fields_of(kind, body))]
    refs = {k: body[k] for k in keys if k is not None and isinstance(body.get(k), str)}
    if paths.needs_nodes(*refs.values()):
        nodes = manager.nodes(scene_id)
        for k, ref in refs.items():
            body[k] = paths.resolve(nodes, ref, scene_id)
    return body


@router.put("/scenes/{scene_id}/materials/{node:path}", response_model=MaterialPublic)
def put_material(scene_id: SceneId, node: NodeRef, body: Material, manager: Manager) -> dict[str, Any]:
    """Assign a material to a node (inherited by its descendants that have none) or to a sim-owned object.

    ``node``: the node's UUID or its path (URL-encoded, or plain: ``car/lens``); the answer names the UUID."""
    return manager.set_material(scene_id, _node_key(manager, scene_id, node), body)   # validated once, by FastAPI


@router.get("/scenes/{scene_id}/materials", response_model=list[MaterialPublic])
def list_materials(scene_id: SceneId, manager: Manager) -> list[dict[str, Any]]:
    return manager.list_materials(scene_id)


@router.delete("/scenes/{scene_id}/materials/{node:path}", status_code=204)
def delete_material(scene_id: SceneId, node: NodeRef, manager: Manager) -> Response:
    manager.delete_material(scene_id, _node_key(manager, scene_id, node))
    return Response(status_code=204)


@router.delete("/scenes/{scene_id}/orphans", response_model=list[OrphanPublic])
def purge_orphans(scene_id: SceneId, manager: Manager) -> list[dict[str, str]]:
    """Delete every orphaned assignment of the scene; answers what was deleted."""
    return manager.purge_orphans(scene_id)


def _answerable(sensor: dict, request: Request) -> None:
    """422 for a sensor that no simulate of this service could answer, said at creation rather than at its first
    simulate, with nothing stored: a camera beyond ``max_camera_pixels`` (one beyond ``max_points`` is traced in
    bands of rows: `service.view_kinds.camera_refusal`), a grid of more cells or a far field of more bins than one
    query may ask (``max_points``). (One stored before a limit was lowered is still refused by its simulate, 413.)"""
    from service.errors import Invalid
    from service.sensor_kinds import kind_of
    from service.simulation import hub_for

    found = kind_of(sensor).refusal(sensor, hub_for(request.app).limits)
    if found is not None:
        why, limit = found
        raise Invalid(why, limit=limit)


def _routes(kind: str, plural: str, schema: Any) -> None:
    @router.post(f"/scenes/{{scene_id}}/{plural}", status_code=201, response_model=AssignmentAdded,
                 name=f"add_{kind}")
    def add(scene_id: SceneId, body: schema, manager: Manager,  # type: ignore[valid-type]
            request: Request) -> dict[str, Any]:
        clean = _resolve_anchors(manager, scene_id, kind, validate_body(kind, body))
        if kind == "sensor":
            _answerable(clean, request)
        added = manager.add_assignment(scene_id, kind, clean)
        if kind in ("light", "sensor") and not added.get("orphaned"):
            added = {**added, "warnings": _far(request, scene_id, kind, str(added["id"]))}
        return added

    @router.get(f"/scenes/{{scene_id}}/{plural}", response_model=list[AssignmentPublic], name=f"list_{plural}")
    def list_(scene_id: SceneId, manager: Manager) -> list[dict[str, Any]]:
        return manager.list_assignments(scene_id, kind)

    @router.get(f"/scenes/{{scene_id}}/{plural}/{{item_id}}", response_model=AssignmentPublic, name=f"get_{kind}")
    def get(scene_id: SceneId, item_id: ItemId, manager: Manager) -> dict[str, Any]:
        return manager.get_assignment(scene_id, kind, item_id)

    @router.delete(f"/scenes/{{scene_id}}/{plural}/{{item_id}}", status_code=204, name=f"delete_{kind}")
    def delete(scene_id: SceneId, item_id: ItemId, manager: Manager) -> Response:
        manager.delete_assignment(scene_id, kind, item_id)
        return Response(status_code=204)


_routes("light", "lights", Light)
_routes("sensor", "sensors", Sensor)
_routes("object", "objects", ObjectCreate)
