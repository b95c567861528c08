"""The one place that switches on a bottom-level kind (see :mod:`tracer.kinds`).

To register a new kind: import its module here and add one branch to each function below that
applies to it (a solid kind to the ``*_solid`` functions, a sensor kind to :func:`cross_sensor`).
Rays arrive in object space; results are object-space.
"""

from __future__ import annotations

from tracer.jit import njit
from tracer.kinds import disk_sensor, mesh, rect_sensor


@njit(cache=True, error_model="numpy", inline="always")
def intersect_solid(sa, inst, ox, oy, oz, dx, dy, dz, t_max, any_hit, stack, tstack):
    """``(hit, t, slot, u, v)`` of the ray with solid instance ``inst`` (closest, or any with ``any_hit``)."""
    kind = sa.inst_kind[inst]
    if kind == mesh.KIND:
        return mesh.traverse(sa, sa.inst_geom[inst], ox, oy, oz, dx, dy, dz, t_max, any_hit, stack, tstack)
    return False, 0.0, -1, 0.0, 0.0


@njit(cache=True, error_model="numpy", inline="always")
def primitive_solid(sa, inst, slot):
    """Primitive id reported for a hit at ``slot`` of solid instance ``inst``."""
    kind = sa.inst_kind[inst]
    if kind == mesh.KIND:
        return mesh.primitive_id(sa, sa.inst_geom[inst], slot)
    return -1


@njit(cache=True, error_model="numpy", inline="always")
def normal_solid(sa, inst, slot):
    """Unnormalised object-space geometric normal at ``slot`` of solid instance ``inst``."""
    kind = sa.inst_kind[inst]
    if kind == mesh.KIND:
        return mesh.object_normal(sa, sa.inst_geom[inst], slot)
    return 0.0, 0.0, 1.0


@njit(cache=True, error_model="numpy", _nrt=False)
def shading_normal_object(sa, inst, prim, u, v):
    """Object-space shading normal ``(nx, ny, nz, interpolated)`` of primitive ``prim`` at ``(u, v)``."""
    kind = sa.inst_kind[inst]
    if kind == mesh.KIND:
        return mesh.object_shading_normal(sa, sa.inst_geom[inst], prim, u, v)
    return 0.0, 0.0, 1.0, False


@njit(cache=True, error_model="numpy", _nrt=False)
def point_object(sa, inst, prim, u, v):
    """Object-space surface point of primitive ``prim`` at ``(u, v)``."""
    kind = sa.inst_kind[inst]
    if kind == mesh.KIND:
        return mesh.object_point(sa, sa.inst_geom[inst], prim, u, v)
    if kind == disk_sensor.KIND or kind == rect_sensor.KIND:
        return u, v, 0.0
    return 0.0, 0.0, 0.0


@njit(cache=True, error_model="numpy", _nrt=False)
def cross_sensor(sa, inst, ox, oy, oz, dx, dy, dz, t_max):
    """``(hit, t, u, v)`` of the segment with sensor instance ``inst``."""
    kind = sa.inst_kind[inst]
    if kind == disk_sensor.KIND:
        return disk_sensor.cross(ox, oy, oz, dx, dy, dz, t_max)
    if kind == rect_sensor.KIND:
        return rect_sensor.cross(ox, oy, oz, dx, dy, dz, t_max)
    return False, 0.0, 0.0, 0.0
