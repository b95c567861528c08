"""The contract of a bottom-level kind: what an instance of the top level can be.

A kind is one module of `tracer.kinds`, registered by its entry in `tracer.kinds.REGISTRY`; `tracer.kinds.dispatch`
(the only place that tests the tag) is written out from the registry. A kind holds:

- ``KIND`` : int — its tag in `SceneArrays.inst_kind`;
- ``SENSOR`` : bool — a sensor is recorded by `tracer.accel.traverse.sensor_crossings` and invisible to closest-hit
  and any-hit queries; a solid is hit;
- ``GEOMETRY`` : str or None — what `tracer.Scene.instance_geometry` reports for it (None: its geometry's id);
- ``OBJECT_BOUNDS`` : (6,) float64 object-space box, where it is fixed (a mesh's comes from its vertices);
- its jitted routines in object space (rays arrive in object space, results are object-space), each taking the
  scene arrays and the instance id first, as the dispatch calls them:
  a solid's ``intersect(sa, inst, ox, oy, oz, dx, dy, dz, t_max, any_hit, stack, tstack) -> (hit, t, slot, u, v)``,
  ``primitive(sa, inst, slot) -> prim``, ``normal(sa, inst, slot, u, v) -> (nx, ny, nz)`` (geometric, any length),
  ``shading_normal(sa, inst, prim, u, v) -> (nx, ny, nz, interpolated)`` and ``point(sa, inst, prim, u, v)``;
  a sensor's ``cross(sa, inst, ox, oy, oz, dx, dy, dz, t_max) -> (hit, t, u, v)`` and ``point``;
- a sensor's ``placement(...) -> (4, 4) world_from_object``: its arguments checked (`TracerError` naming what is
  wrong), used by `tracer.Scene.add_shape`.

The helpers below check the vectors a placement takes.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from tracer.errors import TracerError


def vec3(x: Any, what: str) -> np.ndarray:
    """`x` as 3 finite float64 numbers; `TracerError` naming `what` otherwise."""
    try:
        a = np.array(x, dtype=np.float64)
    except (TypeError, ValueError):
        raise TracerError(f"{what} must be 3 numbers") from None
    if a.shape != (3,):
        raise TracerError(f"{what} must have shape (3,), got {a.shape}")
    if not np.isfinite(a).all():
        raise TracerError(f"{what} must be finite, got {a.tolist()}")
    return a


def orthonormal_basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing unit ``n`` to a right-handed basis (Duff et al., JCGT 2017)."""
    sign = 1.0 if n[2] >= 0.0 else -1.0
    a = -1.0 / (sign + n[2])
    b = n[0] * n[1] * a
    t1 = np.array([1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]])
    t2 = np.array([b, sign + n[1] * n[1] * a, -n[1]])
    return t1, t2
