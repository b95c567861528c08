"""Disk: one disk receiver answering its mean illuminance (lx) — the wire's disk sensor.

``{"type": "disk", "center": (3,) m, "normal": (3,) front side, "radius": m}``: the `points` kind with one point;
the answer is its `IlluminanceResult` (``lux`` (1,)).
"""

from __future__ import annotations

from tracer.sensors import points
from tracer.sensors.base import IlluminanceResult, Probe

TYPE = "disk"
FORWARD_ONLY = False
OBSERVES = True


def probe(sim, body: dict) -> Probe:
    return points.probe(sim, {"points": [body.get("center")], "normals": [body.get("normal")],
                              "radius": body.get("radius")})


def answer(sim, probe: Probe, res: IlluminanceResult) -> IlluminanceResult:
    return res
