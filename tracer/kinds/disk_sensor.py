"""Kind 1: disk sensor, the unit disk ``x^2 + y^2 <= 1`` in the plane ``z = 0`` of object space.

Front side: object ``+z``. The instance transform (built by :meth:`tracer.Scene.add_disk_sensor`)
maps it onto a disk of the given centre, normal and radius. A sensor records the rays that cross
it and changes nothing: closest-hit and any-hit queries do not see it.

Crossing result ``(u, v)``: the object-space point, in the unit disk.
"""

from __future__ import annotations

import numpy as np

from tracer.jit import njit

KIND = 1
SENSOR = True
OBJECT_BOUNDS = np.array([-1.0, -1.0, 0.0, 1.0, 1.0, 0.0])


@njit(cache=True, error_model="numpy", _nrt=False)
def cross(ox, oy, oz, dx, dy, dz, t_max):
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
