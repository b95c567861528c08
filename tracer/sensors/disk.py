"""Disk: one disk receiver answering its mean illuminance (lx) — the wire's disk sensor.

``{"type": "disk", "center": (3,) m, "normal": (3,) front side, "radius": m}``: the `points` kind with one point;
the answer is its `IlluminanceResult` (``lux`` (1,)).
"""

from __future__ import annotations

from typing import Any

from tracer.optics.fields import BodyField, fields
from tracer.sensors import points
from tracer.sensors.base import IlluminanceResult, Probe

TYPE = "disk"
FORWARD_ONLY = False
OBSERVES = True
FIELDS = fields(
    BodyField("center", "point", "The disk's centre [x, y, z], m."),
    BodyField("normal", "direction", "The side that receives (any length, not zero; dimensionless)."),
    BodyField("radius", "number", "The disk's radius, m.", lo=0.0, lo_open=True))
EXAMPLE = {"type": "disk", "name": "desk", "center": [0.5, 0.5, 0.75], "normal": [0.0, 0.0, 1.0], "radius": 0.05}


def _as_points(body: dict) -> dict:
    return {"points": [body.get("center")], "normals": [body.get("normal")], "radius": body.get("radius")}


def check(body: dict) -> Any:
    return points.check(_as_points(body))


def probe(sim, body: dict) -> Probe:
    return points.probe(sim, _as_points(body))


def answer(sim, probe: Probe, res: IlluminanceResult) -> IlluminanceResult:
    return res
