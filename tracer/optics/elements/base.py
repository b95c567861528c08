"""The element contract: a thin sheet with its own physics, in the paper's sense an optical element.

An element is assigned to a node like a material (``PUT /scenes/{id}/materials/{uuid}``) and keeps the
surface contract (`tracer.optics.surfaces.base`: ``NAME``, ``Spec``, ``row``, ``effects``,
``diffuse_only``, ``scatter``), with one more promise: it is thin, so a photon crossing it
stays in the medium it was in (``scatter`` never changes ``med`` or ``depth``) and it has no inside
(no ``medium``). Its side is told by the hit's geometric normal: the front is the side it points to. Elements register
in `tracer/optics/surfaces/dispatch.py` beside the surfaces: at a hit they are one switch.

An element with an axis in its sheet (a polarizer's, a retarder's fast axis) takes it in the node's own frame
(`parse_axis`), so that it turns with the node; `sheet_axis` gives it in world space at a hit.
"""

from __future__ import annotations

from tracer.jit import njit
from tracer.optics.polarization import unit_axis
from tracer.optics.surfaces.base import MaterialError


def parse_axis(v, name: str, where: str) -> tuple[float, float, float]:
    """A direction [x, y, z] in the node's frame, made unit; `MaterialError` naming the field."""
    a = unit_axis(v)
    if a is None:
        raise MaterialError(f"{where}: {name!r} must be 3 finite numbers, not all zero (a direction in the "
                            f"node's frame, in the sheet's plane), got {v!r}"[:300])
    return a


@njit(cache=True, error_model="numpy", _nrt=False)
def sheet_axis(sa, inst, ax, ay, az, ngx, ngy, ngz):
    """The node-frame axis a in world space, projected onto the sheet's plane at a hit with unit geometric normal
    ng (as given where it has no part in the plane). Not normalised."""
    w = sa.world_from_object[inst]
    x = w[0, 0] * ax + w[0, 1] * ay + w[0, 2] * az
    y = w[1, 0] * ax + w[1, 1] * ay + w[1, 2] * az
    z = w[2, 0] * ax + w[2, 1] * ay + w[2, 2] * az
    c = x * ngx + y * ngy + z * ngz
    px, py, pz = x - c * ngx, y - c * ngy, z - c * ngz
    if px * px + py * py + pz * pz > 1e-12 * (x * x + y * y + z * z):
        return px, py, pz
    return x, y, z
