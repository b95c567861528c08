"""Optical files (ray files, measured BRDF tables), uploaded once, content-addressed, shared by every scene.

``POST /optical-files?format=tm25|rays|brdf`` takes the file's raw bytes and answers ``{id, format, bytes, …}``
(201 when stored now, 200 when the same bytes were stored before); a light or material then names it by that id
(``"file": "<id>"``). A file the tracer's reader refuses is a 422 naming what is wrong, and nothing is stored.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from fastapi import APIRouter, Path, Query, Request, Response

router = APIRouter(tags=["optical files"])

FileId = Annotated[str, Path(pattern=r"^[0-9a-f]{64}$",
                             description="an optical file's id: the SHA-256 of its bytes, 64 lowercase hex digits")]
Format = Annotated[Literal["tm25", "rays", "brdf"], Query(description=(
    "what the file holds: `tm25` a binary ANSI/IES TM-25 ray file, `rays` a text ray file (x y z l m n flux per "
    "line, `tracer.optics.lights.rayfile`), `brdf` a measured BRDF table (`tracer.optics.surfaces.measured_brdf`, "
    "or a Zemax / Radiant `.bsdf` file)"))]


def _store(request: Request):
    return request.app.state.optical_files


@router.post("/optical-files", status_code=201, openapi_extra={"requestBody": {"required": True, "content": {
    "application/octet-stream": {"schema": {"type": "string", "format": "binary"}}}}})
async def upload(request: Request, response: Response, format: Format) -> dict[str, Any]:  # noqa: A002 (the wire name)
    """Store a ray file or a BRDF table once; answers its id (SHA-256 of the bytes) and a summary."""
    summary, created = await _store(request).upload(request.stream(), format)
    response.status_code = 201 if created else 200
    return summary


@router.get("/optical-files")
def listing(request: Request) -> list[dict[str, Any]]:
    """Every stored optical file's summary."""
    return list(_store(request).list())


@router.get("/optical-files/{fid}")
def one(fid: FileId, request: Request) -> dict[str, Any]:
    """One stored file's summary: id, format, bytes, and what its reader found (rays and flux, or the table's
    shape and largest albedo)."""
    return dict(_store(request).summary(fid))
