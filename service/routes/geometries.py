"""Meshes: ``POST /geometries/missing``, ``PUT /geometries/{gid}`` (GLB), ``GET /geometries/{gid}``."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request, Response
from starlette.concurrency import run_in_threadpool

from service.routes.deps import GeometryPath, Manager
from service.schemas import GeometryPublic, MissingPublic, MissingQuery

router = APIRouter(tags=["geometries"])


@router.post("/geometries/missing", response_model=MissingPublic)
def missing(body: MissingQuery, manager: Manager) -> dict[str, Any]:
    """Which of these meshes the client still has to upload (in the order asked, without repeats)."""
    return {"missing": manager.missing_geometries(body.ids)}


@router.put(
    "/geometries/{gid}",
    response_model=GeometryPublic,
    openapi_extra={"requestBody": {"required": True, "content": {"model/gltf-binary": {
        "schema": {"type": "string", "format": "binary"}}}}},
)
async def put_geometry(gid: GeometryPath, request: Request, manager: Manager, response: Response) -> dict[str, Any]:
    """Store one mesh (GLB, one primitive). 400 if it does not hash to `gid`, 422 if it is no valid mesh."""
    # `gid` has passed GeometryPath's pattern (422 before this runs); the store checks it once more as it names files
    data = await request.body()
    answer = await run_in_threadpool(manager.put_geometry, gid, data)
    response.status_code = 201 if answer["created"] else 200
    return answer


@router.get("/geometries/{gid}", response_class=Response,
            responses={200: {"content": {"model/gltf-binary": {}}}})
def get_geometry(gid: GeometryPath, manager: Manager) -> Response:
    """The GLB exactly as uploaded."""
    return Response(manager.geometry_glb(gid), media_type="model/gltf-binary")
