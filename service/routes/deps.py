"""Dependencies shared by the routes: the scene manager of the app."""

from __future__ import annotations

from typing import Annotated, Literal

from fastapi import Depends, Path, Query, Request

from service.errors import Invalid
from service.paths import NODE_REF_PATTERN
from service.schemas import GEOMETRY_PATTERN, UUID_PATTERN
from service.state import SceneManager

# path parameters: their forms, in the OpenAPI document and checked (422 naming the parameter) before any lookup
SceneId = Annotated[str, Path(pattern=UUID_PATTERN, description="the scene's id, a UUID (POST /scenes answers it)")]
NodeId = Annotated[str, Path(pattern=UUID_PATTERN, description="a node's UUID, as the CAD adapter pushed it")]
NodeRef = Annotated[str, Path(pattern=NODE_REF_PATTERN, description=(
    "a node's UUID, or its path (`service.paths`: names from the root joined by `/`, `name[2]` for the second "
    "sibling of that name), URL-encoded (`car%2Flens`); also a simulation-owned object's id"))]
ItemId = Annotated[str, Path(pattern=UUID_PATTERN, description="a light's, sensor's or object's id, a UUID")]
GeometryPath = Annotated[str, Path(pattern=GEOMETRY_PATTERN, description="a geometry id: 64 lowercase hex digits "
                                                                          "(`tracer.geometry_id`)")]
JobId = Annotated[str, Path(pattern=r"^[0-9a-f]{32}$", description="a job id: 32 lowercase hex digits")]

# a grid map's colour scale (`service.maps.illuminance_map_figure`)
MapVmin = Annotated[float | None, Query(ge=0.0, le=1e30, allow_inf_nan=False, description=(
    "Bottom of a grid map's colour scale, lx (with `vmax`, a stated range); default by `scale`."))]
MapScale = Annotated[Literal["zero", "data"], Query(description=(
    "Where a grid map's colour scale starts without `vmin`: `zero` (0 lx, an isolux picture) or `data` (the "
    "smallest cell, so that a near-uniform face's non-uniformity fills the colours)."))]


def map_range(vmin: float | None, vmax: float | None) -> None:
    """422 for a stated colour scale whose bottom is not below its top."""
    if vmin is not None and vmax is not None and vmin >= vmax:
        raise Invalid(f"vmin ({vmin:g} lx) must be below vmax ({vmax:g} lx): the colour scale runs from vmin to vmax")


def get_manager(request: Request) -> SceneManager:
    return request.app.state.manager


Manager = Annotated[SceneManager, Depends(get_manager)]
