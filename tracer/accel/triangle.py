"""Watertight ray–triangle intersection (Woop, Benthin and Wald, JCGT 2(1), 2013), in float64.

The ray is sheared so that it runs along +z from the origin; the 2-D edge functions U, V, W of the
sheared triangle are then evaluated with the *same* expression for an edge shared by two triangles
(with opposite sign), so a ray through a shared edge or vertex hits at least one of them: nothing
slips between triangles. Everything is float64; the vertices come from float32 tessellations,
so at 1e5 m a vertex is exact and the edge functions keep ~11 spare digits.

Conventions: each triangle is 9 consecutive values ``v0, v1, v2`` of a flat array. A hit returns barycentrics ``(u, v)``
with ``p = (1 - u - v) v0 + u v1 + v v2``. Both faces are hit (no culling). Degenerate (zero-area)
triangles give ``det == 0`` and never hit; no division by zero happens before that test.
"""

from __future__ import annotations

import numpy as np

from tracer.jit import njit


@njit(cache=True, error_model="numpy", inline="always")
def ray_setup(dx, dy, dz):
    """Per-ray constants of the watertight test.

    Returns ``(kx, ky, kz, sx, sy, sz)``: the axis permutation (kz is the dominant axis of ``d``,
    kx/ky swapped when ``d[kz] < 0`` to keep the winding) and the shear constants.
    """
    ax = abs(dx)
    ay = abs(dy)
    az = abs(dz)
    if ax >= ay and ax >= az:
        kz = 0
    elif ay >= az:
        kz = 1
    else:
        kz = 2
    kx = kz + 1
    if kx == 3:
        kx = 0
    ky = kx + 1
    if ky == 3:
        ky = 0
    dkz = dx if kz == 0 else (dy if kz == 1 else dz)
    if dkz < 0.0:
        kx, ky = ky, kx
    dkx = dx if kx == 0 else (dy if kx == 1 else dz)
    dky = dx if ky == 0 else (dy if ky == 1 else dz)
    sz = 1.0 / dkz
    sx = dkx * sz   # one division per ray, not three: any shear works, as long as every triangle gets the same
    sy = dky * sz
    return kx, ky, kz, sx, sy, sz


@njit(cache=True, error_model="numpy", inline="always")
def origin_setup(o0, o1, o2, kx, ky, kz):
    """The ray origin in the axis order of :func:`ray_setup`: ``(okx, oky, okz)``, once per ray, not per
    triangle (selected in the triangle loop, it cost three branches per triangle)."""
    okx = o0 if kx == 0 else (o1 if kx == 1 else o2)
    oky = o0 if ky == 0 else (o1 if ky == 1 else o2)
    okz = o0 if kz == 0 else (o1 if kz == 1 else o2)
    return okx, oky, okz


@njit(cache=True, error_model="numpy", inline="always")
def intersect_triangle(tri, j, okx, oky, okz, kx, ky, kz, sx, sy, sz, t_max):
    """Test ray ``(o, d)`` (``d`` given through :func:`ray_setup`, ``o`` through :func:`origin_setup`) against
    triangle row ``tri[j]``.

    Parameters
    ----------
    tri : (9 m,) float32 or float64
        Triangle vertices ``v0, v1, v2`` in the ray's space, flat, 9 per triangle (arithmetic is
        float64 either way).
    j : int
        Triangle to test (>= 0).
    okx, oky, okz : float
        Ray origin, permuted (:func:`origin_setup`).
    kx, ky, kz, sx, sy, sz
        From :func:`ray_setup`.
    t_max : float
        Only hits with ``0 < t < t_max`` count.

    Returns
    -------
    (hit, t, u, v) : (bool, float, float, float)
    """
    # unsigned offsets: numba then checks no index for wraparound (three instructions per load)
    q = np.uint64(9 * j)
    ux = np.uint64(kx)
    uy = np.uint64(ky)
    uz = np.uint64(kz)
    akz = tri[q + uz] - okz
    bkz = tri[q + np.uint64(3) + uz] - okz
    ckz = tri[q + np.uint64(6) + uz] - okz
    ax = (tri[q + ux] - okx) - sx * akz
    ay = (tri[q + uy] - oky) - sy * akz
    bx = (tri[q + np.uint64(3) + ux] - okx) - sx * bkz
    by = (tri[q + np.uint64(3) + uy] - oky) - sy * bkz
    cx = (tri[q + np.uint64(6) + ux] - okx) - sx * ckz
    cy = (tri[q + np.uint64(6) + uy] - oky) - sy * ckz
    uu = cx * by - cy * bx
    vv = ax * cy - ay * cx
    ww = bx * ay - by * ax
    if (uu < 0.0 or vv < 0.0 or ww < 0.0) and (uu > 0.0 or vv > 0.0 or ww > 0.0):
        return False, 0.0, 0.0, 0.0
    det = uu + vv + ww
    if det == 0.0:
        return False, 0.0, 0.0, 0.0
    tt = uu * (sz * akz) + vv * (sz * bkz) + ww * (sz * ckz)
    if det > 0.0:
        if tt <= 0.0 or tt >= t_max * det:
            return False, 0.0, 0.0, 0.0
    else:
        if tt >= 0.0 or tt <= t_max * det:
            return False, 0.0, 0.0, 0.0
    inv = 1.0 / det
    return True, tt * inv, vv * inv, ww * inv
