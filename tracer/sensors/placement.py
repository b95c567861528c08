"""Where a receiver sits: on the surface its point lies on, just in front of it.

A query point may lie exactly on a surface (a receiver on the floor). The mesh is stored in float32,
so the surface the rays meet may lie a little above or below the point given. `place_receivers`
therefore probes along the normal from `probe_distance(p)` (1e-6 m + 2⁻²⁰ × the coordinate
magnitude, 16 float32 ulps) above the point down to as far below it; where it meets a surface, the
receiver is put on the surface the rays actually meet. In every case it then sits `sensor_offset`
in front: max(1e-9 m, 2⁻⁴⁴ × the coordinate magnitude), 5.7e-9 m at 1e5 m from the origin, ~400
float64 ulps there — far above the error of the crossing distances (computed in object space, where
an instance's translation has cancelled), so light arriving at the floor crosses the receiver
before it hits the floor, and far too small to change the answer. Where the facet met is tilted
against the receiver by float32 rounding (≲ 1e-7 rad on a tessellated sphere), the receiver is moved
a further 2 r sin(tilt), so that no part of the disk lies behind the facet. Light leaving the floor crosses
the receiver from behind (spawned rays start 2⁻³² × magnitude off the surface) and is not counted.
"""

from __future__ import annotations

import numpy as np

from tracer.accel.traverse import closest_each
from tracer.compile_locks import first_use


def sensor_offset(p: np.ndarray) -> float:
    """How far a query patch is moved off its plane along its normal, m (see the module docstring)."""
    return max(1e-9, 2.0 ** -44 * float(np.max(np.abs(p))))


def probe_distance(p: np.ndarray) -> float:
    """How far from a query point a surface is taken to be the one it lies on, m (16 float32 ulps)."""
    return 1e-6 + 2.0 ** -20 * float(np.max(np.abs(p)))


def place_receivers(sa, points: np.ndarray, normals: np.ndarray, radius: float) -> np.ndarray:
    """Receiver centres (k, 3): each point moved onto the surface it lies on (if any, within
    `probe_distance`) and then in front of it along its unit normal (see the module docstring).

    The offset is `sensor_offset`, plus, where the surface met is tilted against the receiver by less
    than 1e-3 rad (float32 rounding of a facet the point lies on), 2 r sin(tilt), so that the whole
    disk of radius r stays in front of the facet the rays meet.
    """
    k = len(points)
    h = np.array([probe_distance(p) for p in points])
    origins = np.ascontiguousarray(points + h[:, None] * normals)
    hit_t, hit_inst, hit_normal = np.empty(k), np.empty(k, np.int64), np.empty((k, 3))
    with first_use("probe"):
        closest_each(sa, origins, np.ascontiguousarray(-normals), np.full(k, np.inf), hit_t, hit_inst, hit_normal)
    out = np.empty_like(points)
    for i in range(k):
        base = points[i]
        extra = 0.0
        if hit_inst[i] >= 0 and hit_t[i] <= 2.0 * h[i]:
            base = origins[i] - hit_t[i] * normals[i]
            sin_tilt = float(np.linalg.norm(np.cross(hit_normal[i], normals[i])))
            if sin_tilt < 1e-3:
                extra = 2.0 * radius * sin_tilt
        out[i] = base + (sensor_offset(base) + extra) * normals[i]
    return out
