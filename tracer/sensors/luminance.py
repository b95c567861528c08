"""Luminance: a luminance meter, the mean luminance (cd/m²) over a cone of directions from one point.

``{"type": "luminance", "position": (3,) m, "direction": (3,) any non-zero length, "aperture_deg": degrees}``

| field | type | unit | range | default |
| --- | --- | --- | --- | --- |
| position | 3 floats | m | finite | required |
| direction | 3 floats | — | not zero | required |
| aperture_deg | float | ° | (0, 180]: the cone's full angle (a meter's acceptance angle) | 1.0 |

Answered by paths from the eye (`tracer.transport.radiance`; estimator "auto" or "backward"), uniform in solid
angle over the cone. The answer: `tracer.sensors.views.LuminanceResult` with scalar ``luminance`` and ``stderr``
(cd/m²). A meter looking at a Lambertian surface of reflectance ρ under illuminance E reads ρE/π.
"""

from __future__ import annotations

import math

import numpy as np

from tracer.optics.fields import BodyField, fields
from tracer.optics.frames import onb
from tracer.sensors.base import IlluminanceResult, Probe, vec3
from tracer.sensors.views import LuminanceResult, angle, check_fields, luminance_result, unit
from tracer.transport.radiance import CONE, ViewArrays

TYPE = "luminance"
FORWARD_ONLY = False
OBSERVES = False
DEFAULT_APERTURE_DEG = 1.0
FIELDS = fields(
    BodyField("position", "point", "Where the meter is (its eye) [x, y, z], m."),
    BodyField("direction", "direction", "Where it looks: the cone's axis (any length, not zero; dimensionless)."),
    BodyField("aperture_deg", "number", f"The cone's full angle (the meter's acceptance angle), degrees; default "
              f"{DEFAULT_APERTURE_DEG:g}.", required=False, lo=0.0, hi=180.0, lo_open=True))
EXAMPLE = {"type": "luminance", "name": "desk seen from the chair", "position": [0.0, -1.0, 1.2],
           "direction": [0.0, 1.0, -0.6], "aperture_deg": 1.0}


def check(body: dict) -> tuple[np.ndarray, np.ndarray, float]:
    """The body checked without a scene: (position, unit direction, half aperture in radians); `SimulationError`
    naming the field otherwise."""
    check_fields(body, TYPE, FIELDS)
    o = vec3(body.get("position"), "position")
    axis = unit(vec3(body.get("direction"), "direction"), "direction")
    f = FIELDS["aperture_deg"]
    return o, axis, math.radians(angle(body, "aperture_deg", f.lo, f.hi, DEFAULT_APERTURE_DEG)) / 2.0


def probe(sim, body: dict) -> Probe:
    o, axis, half = check(body)
    one_minus_cos = 2.0 * math.sin(half / 2.0) ** 2   # 1 − cos, exact for small apertures
    t, b = onb(*axis)
    view = ViewArrays(np.array([CONE], np.int64), o[None, :], axis[None, :], np.array([t]), np.array([b]),
                      np.zeros((1, 3)), np.array([1.0 - one_minus_cos]), np.array([2.0 * math.pi * one_minus_cos]))
    return Probe(o[None, :], axis[None, :], view=view)


def answer(sim, probe: Probe, res: IlluminanceResult) -> LuminanceResult:
    return luminance_result(sim, res, None)
