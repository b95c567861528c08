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

`meters` measures k meters in one run; `conoscope` places them on a polar grid around one point (luminance against
viewing angle, ``POST /scenes/{id}/luminance/conoscope``); `half_angle` reads a view's spread from it (the polar angle
where the luminance falls to half its on-axis value).
"""

from __future__ import annotations

import math

import numpy as np

from tracer.errors import SimulationError
from tracer.optics.fields import BodyField, fields
from tracer.optics.frames import onb
from tracer.sensors.base import IlluminanceResult, Probe, vec3
from tracer.sensors.views import LuminanceResult, angle, check_fields, luminance_result, unit
from tracer.transport.query import query as make_query
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


def meters(sim, positions, directions, aperture_deg: float = DEFAULT_APERTURE_DEG, query=None, progress=None,
           cancel=None, **options) -> LuminanceResult:
    """The luminance (cd/m²) each of k meters reads, measured together (one run, one stop rule over all of them):
    `LuminanceResult` with ``luminance`` and ``stderr`` of shape (k,). `query`: a `tracer.transport.query.Query`, or
    `options` as `tracer.simulate.Simulation.run` takes them (estimator "auto" or "backward")."""
    q = make_query(**options) if query is None else query
    if q.estimator == "forward":
        raise SimulationError("luminance meters are answered by paths from the eye; the forward estimator cannot")
    body = {"positions": positions, "directions": directions, "aperture_deg": aperture_deg}
    probe, res = sim.measure(meters_probe, body, q, progress, cancel)
    return luminance_result(sim, res, (probe.view.kind.shape[0],))


#: the conoscope's limits: polar angles below grazing, and rings and azimuths a plot can show
CONOSCOPE_MAX_THETA_DEG = 85.0
CONOSCOPE_RINGS = (2, 46)
CONOSCOPE_AZIMUTHS = (1, 72)


def conoscope_views(point, normal, theta_max_deg: float, rings: int, azimuths: int, distance: float,
                    phi_zero=None) -> dict[str, np.ndarray]:
    """Where the meters of a conoscopic view stand and look: ``rings`` polar angles θ from 0 to `theta_max_deg`
    (degrees, from `normal`: the face's normal towards the viewer) times ``azimuths`` azimuths φ from 0 (`phi_zero`,
    any direction not along `normal`, projected into the face's plane; default `onb`'s tangent) in steps of
    360°/azimuths; one meter on the axis for θ = 0. Returns {"theta_deg": (rings,), "phi_deg": (azimuths,),
    "eyes": (k, 3) m, "directions": (k, 3) unit, each meter looking at `point` from `distance` m, "cell": (k, 2)
    int (ring, azimuth) of each meter, ring 0's one meter at azimuth 0, "normal" and "phi_zero": the unit vectors
    used}. `SimulationError` naming the argument."""
    p = vec3(point, "point")
    n = unit(vec3(normal, "normal"), "normal")
    if not 0.0 < float(theta_max_deg) <= CONOSCOPE_MAX_THETA_DEG:
        raise SimulationError(f"theta_max_deg must be in (0, {CONOSCOPE_MAX_THETA_DEG:g}] degrees, got "
                              f"{theta_max_deg}")
    for name, value, (lo, hi) in (("rings", rings, CONOSCOPE_RINGS), ("azimuths", azimuths, CONOSCOPE_AZIMUTHS)):
        if int(value) != value or not lo <= value <= hi:
            raise SimulationError(f"{name} must be a whole number in [{lo}, {hi}], got {value}")
    if not (math.isfinite(distance) and distance > 0.0):
        raise SimulationError(f"distance must be a positive number of metres, got {distance}")
    if phi_zero is None:
        e1 = np.asarray(onb(*n)[0], float)
    else:
        a = vec3(phi_zero, "phi_zero")
        e1 = a - np.dot(a, n) * n
        if float(np.linalg.norm(e1)) <= 1e-9 * max(float(np.linalg.norm(a)), 1e-300):
            raise SimulationError("phi_zero lies along the normal: give a direction in (or across) the face's plane")
        e1 = e1 / np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    theta = np.linspace(0.0, float(theta_max_deg), int(rings))
    phi = 360.0 * np.arange(int(azimuths)) / int(azimuths)
    cell = [(0, 0)] + [(i, j) for i in range(1, int(rings)) for j in range(int(azimuths))]
    t = np.radians([theta[i] for i, _ in cell])[:, None]
    f = np.radians([phi[j] for _, j in cell])[:, None]
    towards_eye = np.sin(t) * (np.cos(f) * e1 + np.sin(f) * e2) + np.cos(t) * n
    return {"theta_deg": theta, "phi_deg": phi, "eyes": p + float(distance) * towards_eye,
            "directions": -towards_eye, "cell": np.array(cell, np.int64), "normal": n, "phi_zero": e1}


def conoscope(sim, point, normal, theta_max_deg: float = 80.0, rings: int = 9, azimuths: int = 12,
              distance: float = 0.5, aperture_deg: float = DEFAULT_APERTURE_DEG, phi_zero=None,
              **query) -> tuple[dict[str, np.ndarray], LuminanceResult]:
    """A conoscopic view of `point`: the luminance (cd/m²) it shows against viewing angle, measured by meters at the
    polar grid of `conoscope_views` in one run (one stop rule over all of them). Returns (the views, with
    "luminance" and "stderr" of shape (rings, azimuths), ring 0's one reading repeated; the meters' own
    `LuminanceResult`). `query`: as `meters`'."""
    views = conoscope_views(point, normal, theta_max_deg, rings, azimuths, distance, phi_zero)
    res = meters(sim, views["eyes"], views["directions"], aperture_deg, **query)
    grid = np.empty((int(rings), int(azimuths)))
    err = np.empty_like(grid)
    lum, se = np.asarray(res.luminance, float), np.asarray(res.stderr, float)
    grid[0], err[0] = lum[0], se[0]
    grid[1:] = lum[1:].reshape(int(rings) - 1, int(azimuths))
    err[1:] = se[1:].reshape(int(rings) - 1, int(azimuths))
    return {**views, "luminance": grid, "stderr": err}, res


def ring_means(luminance, stderr) -> tuple[np.ndarray, np.ndarray]:
    """A conoscopic view's luminance averaged over each ring's azimuths, and its standard error: (rings,) cd/m² each,
    from `conoscope`'s (rings, azimuths) grids (ring 0, the axis, is one reading repeated: its own error)."""
    lum, err = np.asarray(luminance, float), np.asarray(stderr, float)
    if lum.ndim != 2 or lum.shape != err.shape or lum.shape[0] < 2:
        raise SimulationError(f"luminance and stderr must be (rings, azimuths) grids of the same shape with at least "
                              f"2 rings, got {lum.shape} and {err.shape}")
    mean = lum.mean(axis=1)
    se = np.sqrt((err ** 2).sum(axis=1)) / lum.shape[1]
    mean[0], se[0] = lum[0, 0], err[0, 0]
    return mean, se


def half_angle(theta_deg, luminance, stderr) -> tuple[float, float, bool]:
    """The half-luminance viewing angle of a conoscopic view (what a display's viewing angle or a film's spread is
    quoted as): the polar angle, degrees, at which the luminance averaged over each ring's azimuths (`ring_means`)
    first falls below half its on-axis value, interpolated linearly between the two rings around it. Returns (angle,
    its standard error, True); the error is the rings' errors carried through the interpolation to first order (the
    rings are read by different meters: independent). Where no ring falls that far the angle is the view's largest,
    its error 0 and the flag False: the spread is at least that wide. A view dark on its axis has none: (nan, nan,
    False). `theta_deg` (rings,) ascending from 0; `luminance`, `stderr` (rings, azimuths) cd/m²."""
    theta = np.asarray(theta_deg, float)
    mean, se = ring_means(luminance, stderr)
    if theta.shape != mean.shape or theta[0] != 0.0 or not (np.diff(theta) > 0).all():
        raise SimulationError(f"theta_deg must be the rings' {mean.size} polar angles, ascending from 0, got "
                              f"{theta.tolist()}")
    if not mean[0] > 0.0:
        return math.nan, math.nan, False
    half = 0.5 * mean[0]
    below = np.nonzero(mean[1:] < half)[0]
    if below.size == 0:
        return float(theta[-1]), 0.0, False
    b = int(below[0]) + 1
    a = b - 1
    span, drop = theta[b] - theta[a], mean[a] - mean[b]
    angle_deg = theta[a] + span * (mean[a] - half) / drop
    d_a = span * (half - mean[b]) / drop ** 2     # ∂angle/∂L_a, ∂angle/∂L_b, ∂angle/∂L_0 (through the half)
    d_b = span * (mean[a] - half) / drop ** 2
    d_0 = -span / (2.0 * drop)
    if a == 0:   # L_a is the axis reading itself
        var = (d_a + d_0) ** 2 * se[0] ** 2 + d_b ** 2 * se[b] ** 2
    else:
        var = d_a ** 2 * se[a] ** 2 + d_b ** 2 * se[b] ** 2 + d_0 ** 2 * se[0] ** 2
    return float(angle_deg), float(math.sqrt(var)), True
