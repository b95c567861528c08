"""Points: the illuminance (lx) on the front side of a small disk receiver at each point, averaged over the disk.

``{"type": "points", "points": (k, 3) m, "normals": (k, 3) front sides (any non-zero length), "radius": m}``
(radius default `DEFAULT_RADIUS`). Both estimators answer it: forward photons crossing the disks, or backward
paths from uniform points of each disk. The answer: `IlluminanceResult`, ``lux`` (k,).
"""

from __future__ import annotations

import math

import numpy as np

from tracer.errors import SimulationError
from tracer.sensors.base import IlluminanceResult, Probe, vectors
from tracer.sensors.placement import place_receivers

TYPE = "points"
FORWARD_ONLY = False
OBSERVES = True
DEFAULT_RADIUS = 0.05          # m: disk receiver radius when the query gives none


FIELDS = None                  # not a stored sensor: the body of an illuminance query


def check(body: dict) -> tuple[np.ndarray, np.ndarray, float]:
    """The body checked: (points (k, 3) m, unit normals (k, 3), radius m)."""
    pts = vectors(body.get("points"), "points")
    k = len(pts)
    if k == 0:
        raise SimulationError("points must hold at least one point")
    nrm = vectors(body.get("normals"), "normals", k)
    ln = np.linalg.norm(nrm, axis=1)
    if np.any(ln <= 0):
        raise SimulationError(f"normal {int(np.argmax(ln <= 0))} is the zero vector")
    nrm = nrm / ln[:, None]
    radius = body.get("radius")
    r = DEFAULT_RADIUS if radius is None else radius
    if isinstance(r, bool) or not isinstance(r, int | float) or not (0 < r < math.inf):
        raise SimulationError(f"radius must be a positive finite number of metres, got {radius!r}")
    return pts, nrm, float(r)


def probe(sim, body: dict) -> Probe:
    pts, nrm, r = check(body)
    return Probe(place_receivers(sim.arrays, pts, nrm, r), nrm, r)


def answer(sim, probe: Probe, res: IlluminanceResult) -> IlluminanceResult:
    return res
