"""Kind 0: a triangle mesh with its binned-SAH BVH (:mod:`tracer.accel.blas`), one per unique geometry.

The ray arrives in object space and walks the geometry's 4-wide rows (:func:`tracer.accel.wide.traverse_rows`);
``slot`` results are rows of the packed triangle arrays (triangles of ``sa.tri_v``, leaf order), turned into the
caller's primitive id by :func:`primitive_id`.
"""

from __future__ import annotations

import numpy as np

from tracer.accel.wide import traverse_rows
from tracer.jit import njit

KIND = 0
SENSOR = False
GEOMETRY = None   # an instance reports its geometry's id


@njit(cache=True, error_model="numpy", inline="always")
def intersect(sa, inst, ox, oy, oz, dx, dy, dz, t_max, any_hit, stack, tstack):
    """The kind's entry (`tracer.kinds.base`): :func:`traverse` in the instance's geometry."""
    return traverse(sa, sa.inst_geom[inst], ox, oy, oz, dx, dy, dz, t_max, any_hit, stack, tstack)


@njit(cache=True, error_model="numpy", inline="always")
def primitive(sa, inst, slot):
    """The caller's triangle index of row ``slot``."""
    return sa.tri_prim[slot]


@njit(cache=True, error_model="numpy", inline="always")
def normal(sa, inst, slot, u, v):
    """Unnormalised object-space geometric normal of row ``slot`` (flat: ``u, v`` do not change it)."""
    return object_normal(sa, sa.inst_geom[inst], slot)


@njit(cache=True, error_model="numpy", _nrt=False)
def shading_normal(sa, inst, prim, u, v):
    """Object-space shading normal ``(nx, ny, nz, interpolated)`` of triangle ``prim`` at ``(u, v)``."""
    return object_shading_normal(sa, sa.inst_geom[inst], prim, u, v)


@njit(cache=True, error_model="numpy", _nrt=False)
def point(sa, inst, prim, u, v):
    """Object-space point of triangle ``prim`` at barycentrics ``(u, v)``."""
    return object_point(sa, sa.inst_geom[inst], prim, u, v)


@njit(cache=True, error_model="numpy", inline="always")
def traverse(sa, g, ox, oy, oz, dx, dy, dz, t_max, any_hit, stack, tstack):
    """Closest (or, with ``any_hit``, first found) hit of the object-space ray in geometry ``g``.

    Nearer children first; a pending child is skipped when its entry distance is beyond the best hit
    so far. Returns ``(hit, t, slot, u, v)``; ``slot`` is the triangle's index in ``sa.tri_v``
    (9 values each).
    """
    if sa.geom_ntri[g] == 0:
        return False, 0.0, -1, 0.0, 0.0
    return traverse_rows(sa.bvh_f, sa.bvh_i, sa.tri_v, sa.geom_node0[g], sa.geom_tri0[g], ox, oy, oz, dx, dy, dz,
                         t_max, any_hit, stack, tstack)


@njit(cache=True, error_model="numpy", inline="always")
def object_normal(sa, g, slot):
    """Unnormalised object-space geometric normal ``(v1 - v0) x (v2 - v0)`` of row ``slot``."""
    t = sa.tri_v
    q = 9 * slot
    # float64 before subtracting: the rows are float32
    x0 = np.float64(t[q])
    y0 = np.float64(t[q + 1])
    z0 = np.float64(t[q + 2])
    e1x = t[q + 3] - x0
    e1y = t[q + 4] - y0
    e1z = t[q + 5] - z0
    e2x = t[q + 6] - x0
    e2y = t[q + 7] - y0
    e2z = t[q + 8] - z0
    return e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x


@njit(cache=True, error_model="numpy", _nrt=False)
def object_shading_normal(sa, g, prim, u, v):
    """Object-space interpolated vertex normal of triangle ``prim``; geometric where there is none."""
    slot = sa.geom_tri0[g] + sa.prim_slot[sa.geom_tri0[g] + prim]
    if sa.geom_has_normals[g]:
        w = 1.0 - u - v
        tn = sa.tri_n
        nx = w * tn[slot, 0] + u * tn[slot, 3] + v * tn[slot, 6]
        ny = w * tn[slot, 1] + u * tn[slot, 4] + v * tn[slot, 7]
        nz = w * tn[slot, 2] + u * tn[slot, 5] + v * tn[slot, 8]
        if nx != 0.0 or ny != 0.0 or nz != 0.0:
            return nx, ny, nz, True
    nx, ny, nz = object_normal(sa, g, slot)
    return nx, ny, nz, False


@njit(cache=True, error_model="numpy", _nrt=False)
def object_point(sa, g, prim, u, v):
    """Object-space point of triangle ``prim`` at barycentrics ``(u, v)``."""
    slot = sa.geom_tri0[g] + sa.prim_slot[sa.geom_tri0[g] + prim]
    t = sa.tri_v
    q = 9 * slot
    w = 1.0 - u - v
    return (w * t[q] + u * t[q + 3] + v * t[q + 6],
            w * t[q + 1] + u * t[q + 4] + v * t[q + 7],
            w * t[q + 2] + u * t[q + 5] + v * t[q + 8])


def object_bounds_of(vertices: np.ndarray) -> np.ndarray:
    """(6,) float64 object-space box of a mesh (empty box for no vertices)."""
    if len(vertices) == 0:
        return np.array([np.inf, np.inf, np.inf, -np.inf, -np.inf, -np.inf])
    v = np.asarray(vertices, np.float64)
    return np.concatenate([v.min(axis=0), v.max(axis=0)])
