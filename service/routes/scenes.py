"""Scenes and document pushes: ``/scenes``, ``/scenes/{id}``, ``/scenes/{id}/document``, ``/scenes/{id}/nodes``,
``/scenes/{id}/removed-nodes``."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Query, Request, Response
from fastapi.responses import JSONResponse
from starlette.concurrency import run_in_threadpool

from service import paths
from service.errors import Invalid
from service.routes.deps import Manager, SceneId
from service.schemas import DocumentPush, PushPublic, SceneCreate, SceneListItem, ScenePublic

router = APIRouter(tags=["scenes"])


@router.post("/scenes", status_code=201, response_model=SceneListItem)
def create_scene(body: SceneCreate, manager: Manager) -> dict[str, Any]:
    """Create an empty scene (revision 0); 409 if a scene has that name."""
    return manager.create_scene(body.name)


@router.get("/scenes", response_model=list[SceneListItem])
def list_scenes(manager: Manager) -> list[dict[str, Any]]:
    return manager.list_scenes()


@router.get("/scenes/{scene_id}", response_model=ScenePublic)
def get_scene(scene_id: SceneId, manager: Manager) -> dict[str, Any]:
    """Counts, effect set, orphaned assignments and the default material of one scene."""
    return manager.summary(scene_id)


@router.delete("/scenes/{scene_id}", status_code=204)
def delete_scene(scene_id: SceneId, manager: Manager) -> Response:
    manager.delete_scene(scene_id)
    return Response(status_code=204)


@router.get("/scenes/{scene_id}/nodes")
def get_nodes(
    scene_id: SceneId, manager: Manager,
    path: Annotated[str | None, Query(pattern=paths.NODE_REF_PATTERN, description=(
        "Answer the one node at this path (an object, not a list); 404 naming the closest paths if there is "
        "none."))] = None,
    name: Annotated[str | None, Query(pattern=paths.NODE_REF_PATTERN, description=(
        "Only the nodes whose name matches this glob (`*`, `?`, `[abc]`, case-sensitive); a pattern with a "
        "`/` is matched against whole paths (`car/*lens*`)."))] = None,
) -> list[dict[str, Any]] | dict[str, Any]:
    """The current tree: one record per node, in document order.

    Each record: ``uuid``, ``parent``, ``name``, ``transform`` (local, 16 numbers row-major),
    ``geometry``, ``color``, ``instance`` (its tracer instance id, null without geometry), ``path``
    (the name people and scripts use: names from the root joined by ``/``; among siblings sharing a
    name the first in document order keeps it bare, the next are ``name[2]``, ``name[3]``…; a ``/``
    inside a name shows as ``∕``, U+2215; `service.paths`), and what the CAD adapter reconciles a new
    document against: ``world`` (root_from_node, 16 numbers row-major, in the document's length unit),
    ``product`` and ``signature`` (the node's identity record from the last push, null without one).

    ``?path=car/lens`` answers that node alone; ``?name=lens*`` only the nodes whose name matches.
    """
    if path is not None and name is not None:
        raise Invalid("give either path (one node) or name (a glob), not both")
    nodes = manager.nodes(scene_id)
    if path is not None:
        return paths.find(nodes, path, scene_id)
    if name is not None:
        return paths.matching(nodes, name)
    return nodes


@router.get("/scenes/{scene_id}/removed-nodes")
def get_removed_nodes(scene_id: SceneId, manager: Manager) -> list[dict[str, Any]]:
    """The nodes pushes removed that the scene still remembers (``LUMENLINK_REMOVED_KEEP_REVISIONS``,
    ``LUMENLINK_REMOVED_KEEP_DAYS``), oldest removal first: the record ``GET …/nodes`` gave for each when it
    went (``uuid``, ``parent``, ``name``, ``path``, ``transform``, ``world``, ``geometry``, ``product``,
    ``signature``), with ``length_unit``, ``removed_revision``, ``removed_at`` and the ``assignments`` it
    carried. The CAD adapter matches a document's new nodes against them: one that comes back where it was
    gets its UUID again (listed in the push's ``restored_nodes``), and its orphaned assignments are live again.
    """
    return manager.removed_nodes(scene_id)


@router.get("/scenes/{scene_id}/revisions")
def get_revisions(scene_id: SceneId, manager: Manager) -> list[dict[str, Any]]:
    """The scene's history: per accepted push, how many nodes were added, removed, moved… and the seconds."""
    return manager.revisions(scene_id)


DOCUMENT_SCHEMA = DocumentPush.model_json_schema(ref_template="#/components/schemas/{model}")
#: the models the document's schema refers to; `service.app` adds them to the OpenAPI components
DOCUMENT_SCHEMA_DEFS = DOCUMENT_SCHEMA.pop("$defs", {})


@router.put(
    "/scenes/{scene_id}/document",
    response_model=PushPublic,
    openapi_extra={"requestBody": {"required": True, "content": {"application/json": {"schema": DOCUMENT_SCHEMA}}}},
)
async def push_document(scene_id: SceneId, request: Request, manager: Manager, dry_run: bool = False) -> JSONResponse:
    """Push a CAD tree: validate, diff by UUID, rebuild only what changed, store one revision.

    The body (a `DocumentPush`) is decoded here rather than by FastAPI so that a 20,000-node
    document is parsed once, straight from bytes. Its identity records are stored (only those
    that changed) and its ``reconciliation`` is echoed in the answer.

    ``?dry_run=true``: validate and diff exactly as a push would (409 on a stale
    ``base_revision``, 4xx on an invalid body) and answer the same diff with ``"dry_run": true``,
    the assignments it would orphan or restore, ``blas_to_build`` and ``missing_geometries``
    (not an error here); nothing is changed.
    """
    body = await request.body()
    answer = await run_in_threadpool(manager.push, scene_id, body, dry_run)
    return JSONResponse(answer)
