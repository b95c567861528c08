"""Kind 2: rectangle sensor, the unit square ``[0, 1]^2`` in the plane ``z = 0`` of object space.

Front side: object ``+z``, which the instance transform of :meth:`tracer.Scene.add_rect_sensor`
maps to ``u x v``. Crossing result ``(u, v)``: the object-space point, in ``[0, 1]^2`` (fractions
along the sensor's ``u`` and ``v`` edges).
"""

from __future__ import annotations

import numpy as np

from tracer.jit import njit

KIND = 2
SENSOR = True
OBJECT_BOUNDS = np.array([0.0, 0.0, 0.0, 1.0, 1.0, 0.0])


@njit(cache=True, error_model="numpy", _nrt=False)
def cross(ox, oy, oz, dx, dy, dz, t_max):
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
