"""Spawning secondary rays off a surface without re-hitting it, at any coordinate magnitude.

Wächter and Binder (Ray Tracing Gems, 2019, ch. 6, "A fast and robust method for avoiding
self-intersection") offset a hit point along the geometric normal by an amount that scales with
the magnitude of the coordinates (integer steps of the floating-point representation, so the offset
survives any exponent) and by a fixed small amount near the origin, where ulps vanish. They
derived the constants for float32 hit points from barycentrics. Here points are float64 and may
come from ``o + t d`` through a transformed instance, so the error of a coordinate is not bounded
by its own ulp (a rotated, translated instance cancels large terms). We therefore size the offset
from the largest coordinate magnitude, as pbrt's ``OffsetRayOrigin`` sizes it from an error bound:

``delta = max(ABS_OFFSET, REL_OFFSET * max(|px|, |py|, |pz|))``, ``q = p + delta n``,

then step each moved component one more ulp away from ``p`` (so rounding of ``p + delta n`` cannot
undo the move). ``REL_OFFSET = 2^-32`` is ~2e7 float64 ulps — far above the intersection and
transform error (a few hundred ulps) yet ~1e-3 of a float32 ulp of the vertices, i.e. below any
tessellated feature; ``ABS_OFFSET = 2^-36`` m (1.5e-11 m) covers points near the origin reached by
rays from up to ~1e4 m away.
"""

from __future__ import annotations

import math

from tracer.jit import njit

REL_OFFSET = 2.0 ** -32
ABS_OFFSET = 2.0 ** -36


@njit(cache=True, error_model="numpy")
def offset_ray_origin(px, py, pz, ngx, ngy, ngz, dx, dy, dz):
    """Move hit point ``p`` off its surface (normal ``ng``, any length) to the side ``d`` leaves on.

    Parameters
    ----------
    px, py, pz : float
        Hit point, world metres.
    ngx, ngy, ngz : float
        Geometric normal (either orientation).
    dx, dy, dz : float
        Direction of the new ray.

    Returns
    -------
    (x, y, z) : floats
        The new ray origin.
    """
    ln = math.sqrt(ngx * ngx + ngy * ngy + ngz * ngz)
    if not (ln > 0.0):
        return px, py, pz
    nx = ngx / ln
    ny = ngy / ln
    nz = ngz / ln
    if nx * dx + ny * dy + nz * dz < 0.0:
        nx = -nx
        ny = -ny
        nz = -nz
    mag = max(abs(px), abs(py), abs(pz))
    delta = max(ABS_OFFSET, REL_OFFSET * mag)
    qx = px + delta * nx
    qy = py + delta * ny
    qz = pz + delta * nz
    if nx > 0.0:
        qx = math.nextafter(qx, math.inf)
    elif nx < 0.0:
        qx = math.nextafter(qx, -math.inf)
    if ny > 0.0:
        qy = math.nextafter(qy, math.inf)
    elif ny < 0.0:
        qy = math.nextafter(qy, -math.inf)
    if nz > 0.0:
        qz = math.nextafter(qz, math.inf)
    elif nz < 0.0:
        qz = math.nextafter(qz, -math.inf)
    return qx, qy, qz
