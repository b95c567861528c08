"""Kind 1: disk sensor, the unit disk ``x^2 + y^2 <= 1`` in the plane ``z = 0`` of object space.

Front side: object ``+z``. The instance transform (built by :meth:`tracer.Scene.add_disk_sensor`)
maps it onto a disk of the given centre, normal and radius. A sensor records the rays that cross
it and changes nothing: closest-hit and any-hit queries do not see it.

Crossing result ``(u, v)``: the object-space point, in the unit disk.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from tracer.errors import TracerError
from tracer.jit import njit
from tracer.kinds.base import orthonormal_basis, vec3

KIND = 1
SENSOR = True
GEOMETRY = "sensor:disk"   # what `tracer.Scene.instance_geometry` reports
OBJECT_BOUNDS = np.array([-1.0, -1.0, 0.0, 1.0, 1.0, 0.0])


def placement(center: Any, normal: Any, radius: Any) -> np.ndarray:
    """world_from_object (4, 4) of a disk of `center` (m), front side `normal` (any non-zero length) and `radius`
    (m, > 0): the unit disk scaled by r along an orthonormal basis of its plane."""
    c = vec3(center, "disk sensor center")
    n = vec3(normal, "disk sensor normal")
    ln = float(np.linalg.norm(n))
    if not ln > 0.0:
        raise TracerError("disk sensor normal must be non-zero")
    try:
        r = float(radius)
    except (TypeError, ValueError):
        raise TracerError(f"disk sensor radius must be a number, got {radius!r}") from None
    if not (np.isfinite(r) and r > 0.0):
        raise TracerError(f"disk sensor radius must be positive and finite, got {radius!r}")
    n = n / ln
    t1, t2 = orthonormal_basis(n)
    m = np.eye(4)
    m[:3, 0] = r * t1
    m[:3, 1] = r * t2
    m[:3, 2] = n
    m[:3, 3] = c
    return m


@njit(cache=True, error_model="numpy", _nrt=False)
def cross(sa, inst, ox, oy, oz, dx, dy, dz, t_max):
    """``(hit, t, u, v)`` of the object-space segment ``0 < t < t_max`` with the unit disk."""
    if dz == 0.0:
        return False, 0.0, 0.0, 0.0
    t = -oz / dz
    if not (t > 0.0 and t < t_max):
        return False, 0.0, 0.0, 0.0
    u = ox + t * dx
    v = oy + t * dy
    if u * u + v * v > 1.0:
        return False, 0.0, 0.0, 0.0
    return True, t, u, v


@njit(cache=True, error_model="numpy", _nrt=False)
def point(sa, inst, prim, u, v):
    """Object-space point of a crossing at ``(u, v)``: in the plane ``z = 0``."""
    return u, v, 0.0
