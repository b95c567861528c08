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

from tracer.errors import SimulationError
from tracer.optics.fields import BodyField, fields
from tracer.optics.frames import onb
from tracer.sensors.base import IlluminanceResult, Probe, vec3
from tracer.sensors.views import LuminanceResult, angle, check_fields, luminance_result, unit
from tracer.transport.radiance import CONE, ViewArrays, pinhole

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
                      np.zeros((1, 3)), np.array([1.0 - one_minus_cos]), np.array([2.0 * math.pi * one_minus_cos]),
                      *pinhole(1))
    return Probe(o[None, :], axis[None, :], view=view)


def answer(sim, probe: Probe, res: IlluminanceResult) -> LuminanceResult:
    return luminance_result(sim, res, None)


def meters_probe(sim, body: dict) -> Probe:
    """k luminance meters in one query: ``{"positions": (k, 3) m, "directions": (k, 3), "aperture_deg": °}`` (one
    aperture for all); their views are the same cones `probe` makes for one."""
    pos = np.atleast_2d(np.asarray(body.get("positions"), float))
    dirs = np.atleast_2d(np.asarray(body.get("directions"), float))
    if pos.ndim != 2 or pos.shape[1] != 3 or pos.shape[0] < 1 or dirs.shape != pos.shape:
        raise SimulationError(f"positions and directions must be (k, 3) arrays of the same k ≥ 1, got "
                              f"{pos.shape} and {dirs.shape}")
    k = pos.shape[0]
    parts = [check({"type": TYPE, "position": pos[i], "direction": dirs[i],
                    "aperture_deg": body.get("aperture_deg", DEFAULT_APERTURE_DEG)}) for i in range(k)]
    half = parts[0][2]
    one_minus_cos = 2.0 * math.sin(half / 2.0) ** 2
    axes = np.array([p[1] for p in parts])
    frames = [onb(*a) for a in axes]
    view = ViewArrays(np.full(k, CONE, np.int64), np.ascontiguousarray(pos), np.ascontiguousarray(axes),
                      np.array([f[0] for f in frames]), np.array([f[1] for f in frames]), np.zeros((k, 3)),
                      np.full(k, 1.0 - one_minus_cos), np.full(k, 2.0 * math.pi * one_minus_cos), *pinhole(k))
    return Probe(pos, axes, view=view)


def meters(sim, positions, directions, aperture_deg: float = DEFAULT_APERTURE_DEG, **query) -> LuminanceResult:
    """The luminance (cd/m²) each of k meters reads, measured together (one run, one stop rule over all of them):
    `LuminanceResult` with ``luminance`` and ``stderr`` of shape (k,). `query`: the budget options of
    `tracer.simulate.Simulation.run` (estimator "auto" or "backward")."""
    if query.get("estimator", "auto") == "forward":
        raise SimulationError("luminance meters are answered by paths from the eye; the forward estimator cannot")
    body = {"positions": positions, "directions": directions, "aperture_deg": aperture_deg}
    if "target_relative_error" in query:
        query["target"] = query.pop("target_relative_error")
    probe, res = sim.measure(meters_probe, body, **query)
    return luminance_result(sim, res, (probe.view.kind.shape[0],))
