"""The one place that switches on a bottom-level kind (see :mod:`tracer.kinds`), written out from
:data:`tracer.kinds.REGISTRY` by :func:`tracer.jit.kind_switch`: a new kind adds no branch here.

Rays arrive in object space; results are object-space. A solid kind answers the ``*_solid`` functions and
`point_object`; a sensor kind `cross_sensor` and `point_object`.
"""

from __future__ import annotations

from typing import Any

from tracer.jit import kind_switch
from tracer.kinds import REGISTRY

SOLIDS = {k: m for k, m in REGISTRY.items() if not m.SENSOR}
SENSORS = {k: m for k, m in REGISTRY.items() if m.SENSOR}
TAG = "sa.inst_kind[inst]"
INLINE: dict[str, Any] = {"cache": True, "error_model": "numpy", "inline": "always"}
CALL: dict[str, Any] = {"cache": True, "error_model": "numpy", "_nrt": False}

intersect_solid = kind_switch(
    "intersect_solid", "sa, inst, ox, oy, oz, dx, dy, dz, t_max, any_hit, stack, tstack", TAG,
    {k: m.intersect for k, m in SOLIDS.items()}, "(False, 0.0, -1, 0.0, 0.0)",
    doc="``(hit, t, slot, u, v)`` of the ray with solid instance ``inst`` (closest, or any with ``any_hit``).",
    **INLINE)

primitive_solid = kind_switch(
    "primitive_solid", "sa, inst, slot", TAG, {k: m.primitive for k, m in SOLIDS.items()}, "-1",
    doc="Primitive id reported for a hit at ``slot`` of solid instance ``inst``.", **INLINE)

normal_solid = kind_switch(
    "normal_solid", "sa, inst, slot, u, v", TAG, {k: m.normal for k, m in SOLIDS.items()}, "(0.0, 0.0, 1.0)",
    doc="Unnormalised object-space geometric normal of the hit ``(slot, u, v)`` of solid instance ``inst``.",
    **INLINE)

shading_normal_object = kind_switch(
    "shading_normal_object", "sa, inst, prim, u, v", TAG, {k: m.shading_normal for k, m in SOLIDS.items()},
    "(0.0, 0.0, 1.0, False)",
    doc="Object-space shading normal ``(nx, ny, nz, interpolated)`` of primitive ``prim`` at ``(u, v)``.", **CALL)

point_object = kind_switch(
    "point_object", "sa, inst, prim, u, v", TAG, {k: m.point for k, m in REGISTRY.items()}, "(0.0, 0.0, 0.0)",
    doc="Object-space surface point of primitive ``prim`` at ``(u, v)``.", **CALL)

cross_sensor = kind_switch(
    "cross_sensor", "sa, inst, ox, oy, oz, dx, dy, dz, t_max", TAG, {k: m.cross for k, m in SENSORS.items()},
    "(False, 0.0, 0.0, 0.0)", doc="``(hit, t, u, v)`` of the segment with sensor instance ``inst``.", **CALL)
