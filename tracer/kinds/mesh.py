"""Kind 0: a triangle mesh with its binned-SAH BVH (:mod:`tracer.blas`), one per unique geometry.

The ray arrives in object space; ``slot`` results are rows of the packed triangle arrays
(``sa.tri_v``, leaf order), turned into the caller's primitive id by :func:`primitive_id`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from tracer.triangle import intersect_triangle, ray_setup

KIND = 0
SENSOR = False
#: float64 rounding allowance on the slab test's far distance (pbrt: 1 + 2 gamma(3))
BOX_EPS = 1.0 + 8.0 * 1.1102230246251565e-16


@njit(cache=True, error_model="numpy")
def box_hit(box, i, ox, oy, oz, ix, iy, iz, t_max):
    """Slab test of ``box[i]`` against a ray with inverse direction ``(ix, iy, iz)``, ``0 <= t <= t_max``.

    A NaN slab (origin on the slab plane of an axis the ray is parallel to) is ignored, which is
    conservative: such a box is visited.
    """
    tn = 0.0
    tf = t_max
    if ix >= 0.0:
        t0 = (box[i, 0] - ox) * ix
        t1 = (box[i, 3] - ox) * ix
    else:
        t0 = (box[i, 3] - ox) * ix
        t1 = (box[i, 0] - ox) * ix
    t1 *= BOX_EPS
    if t0 > tn:
        tn = t0
    if t1 < tf:
        tf = t1
    if iy >= 0.0:
        t0 = (box[i, 1] - oy) * iy
        t1 = (box[i, 4] - oy) * iy
    else:
        t0 = (box[i, 4] - oy) * iy
        t1 = (box[i, 1] - oy) * iy
    t1 *= BOX_EPS
    if t0 > tn:
        tn = t0
    if t1 < tf:
        tf = t1
    if iz >= 0.0:
        t0 = (box[i, 2] - oz) * iz
        t1 = (box[i, 5] - oz) * iz
    else:
        t0 = (box[i, 5] - oz) * iz
        t1 = (box[i, 2] - oz) * iz
    t1 *= BOX_EPS
    if t0 > tn:
        tn = t0
    if t1 < tf:
        tf = t1
    return tn <= tf


@njit(cache=True, error_model="numpy")
def traverse(sa, g, ox, oy, oz, dx, dy, dz, t_max, any_hit, stack):
    """Closest (or, with ``any_hit``, first found) hit of the object-space ray in geometry ``g``.

    Returns ``(hit, t, slot, u, v)``; ``slot`` is the row in ``sa.tri_v``.
    """
    n_tri = sa.geom_ntri[g]
    if n_tri == 0:
        return False, 0.0, -1, 0.0, 0.0
    node0 = sa.geom_node0[g]
    tri0 = sa.geom_tri0[g]
    kx, ky, kz, sx, sy, sz = ray_setup(dx, dy, dz)
    ix = 1.0 / dx
    iy = 1.0 / dy
    iz = 1.0 / dz
    box = sa.node_box
    na = sa.node_a
    nn = sa.node_n
    tri = sa.tri_v
    best_t = t_max
    best = -1
    bu = 0.0
    bv = 0.0
    sp = 0
    node = 0
    while True:
        gi = node0 + node
        if box_hit(box, gi, ox, oy, oz, ix, iy, iz, best_t):
            c = nn[gi]
            if c > 0:
                first = tri0 + na[gi]
                for j in range(first, first + c):
                    hit, t, u, v = intersect_triangle(tri, j, ox, oy, oz, kx, ky, kz, sx, sy, sz, best_t)
                    if hit:
                        best_t = t
                        best = j
                        bu = u
                        bv = v
                        if any_hit:
                            return True, best_t, best, bu, bv
                if sp == 0:
                    break
                sp -= 1
                node = stack[sp]
            else:
                axis = -c - 1
                neg = ix < 0.0 if axis == 0 else (iy < 0.0 if axis == 1 else iz < 0.0)
                if neg:
                    stack[sp] = node + 1
                    node = na[gi]
                else:
                    stack[sp] = na[gi]
                    node = node + 1
                sp += 1
        else:
            if sp == 0:
                break
            sp -= 1
            node = stack[sp]
    return best >= 0, best_t, best, bu, bv


@njit(cache=True, error_model="numpy")
def primitive_id(sa, g, slot):
    """The caller's triangle index (position in the geometry's ``triangles``) of row ``slot``."""
    return sa.tri_prim[slot]


@njit(cache=True, error_model="numpy")
def object_normal(sa, g, slot):
    """Unnormalised object-space geometric normal ``(v1 - v0) x (v2 - v0)`` of row ``slot``."""
    t = sa.tri_v
    e1x = t[slot, 3] - t[slot, 0]
    e1y = t[slot, 4] - t[slot, 1]
    e1z = t[slot, 5] - t[slot, 2]
    e2x = t[slot, 6] - t[slot, 0]
    e2y = t[slot, 7] - t[slot, 1]
    e2z = t[slot, 8] - t[slot, 2]
    return e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x


@njit(cache=True, error_model="numpy")
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


@njit(cache=True, error_model="numpy")
def object_point(sa, g, prim, u, v):
    """Object-space point of triangle ``prim`` at barycentrics ``(u, v)``."""
    slot = sa.geom_tri0[g] + sa.prim_slot[sa.geom_tri0[g] + prim]
    t = sa.tri_v
    w = 1.0 - u - v
    return (w * t[slot, 0] + u * t[slot, 3] + v * t[slot, 6],
            w * t[slot, 1] + u * t[slot, 4] + v * t[slot, 7],
            w * t[slot, 2] + u * t[slot, 5] + v * t[slot, 8])


def object_bounds_of(vertices: np.ndarray) -> np.ndarray:
    """(6,) float64 object-space box of a mesh (empty box for no vertices)."""
    if len(vertices) == 0:
        return np.array([np.inf, np.inf, np.inf, -np.inf, -np.inf, -np.inf])
    v = np.asarray(vertices, np.float64)
    return np.concatenate([v.min(axis=0), v.max(axis=0)])
