"""Kind 2: rectangle sensor, the unit square ``[0, 1]^2`` in the plane ``z = 0`` of object space.

Front side: object ``+z``, which the instance transform of :meth:`tracer.Scene.add_rect_sensor`
maps to ``u x v``. Crossing result ``(u, v)``: the object-space point, in ``[0, 1]^2`` (fractions
along the sensor's ``u`` and ``v`` edges).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from tracer.errors import TracerError
from tracer.jit import njit
from tracer.kinds.base import vec3

KIND = 2
SENSOR = True
GEOMETRY = "sensor:rect"   # what `tracer.Scene.instance_geometry` reports
OBJECT_BOUNDS = np.array([0.0, 0.0, 0.0, 1.0, 1.0, 0.0])


def placement(origin: Any, u: Any, v: Any) -> np.ndarray:
    """world_from_object (4, 4) of the parallelogram ``origin + a u + b v``, ``a, b`` in [0, 1] (m), front side
    ``u x v``: the unit square mapped by u, v and the unit normal."""
    o = vec3(origin, "rect sensor origin")
    uu = vec3(u, "rect sensor u")
    vv = vec3(v, "rect sensor v")
    n = np.cross(uu, vv)
    ln = float(np.linalg.norm(n))
    if not ln > 1e-12 * float(np.linalg.norm(uu) * np.linalg.norm(vv)) or ln == 0.0:
        raise TracerError("rect sensor u and v must be non-zero and not parallel")
    m = np.eye(4)
    m[:3, 0] = uu
    m[:3, 1] = vv
    m[:3, 2] = n / ln
    m[:3, 3] = o
    return m


@njit(cache=True, error_model="numpy", _nrt=False)
def cross(sa, inst, ox, oy, oz, dx, dy, dz, t_max):
    """``(hit, t, u, v)`` of the object-space segment ``0 < t < t_max`` with the unit square."""
    if dz == 0.0:
        return False, 0.0, 0.0, 0.0
    t = -oz / dz
    if not (t > 0.0 and t < t_max):
        return False, 0.0, 0.0, 0.0
    u = ox + t * dx
    v = oy + t * dy
    if u < 0.0 or u > 1.0 or v < 0.0 or v > 1.0:
        return False, 0.0, 0.0, 0.0
    return True, t, u, v


@njit(cache=True, error_model="numpy", _nrt=False)
def point(sa, inst, prim, u, v):
    """Object-space point of a crossing at ``(u, v)``: in the plane ``z = 0``."""
    return u, v, 0.0
