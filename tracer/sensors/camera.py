"""Camera: a pinhole camera's image, the mean luminance (cd/m²) over each pixel, with its standard error.

``{"type": "camera", "position": (3,) m, "look_at": (3,) m, "up": (3,), "fov_deg": degrees, "width": px,
"height": px}``

| field | type | unit | range | default |
| --- | --- | --- | --- | --- |
| position | 3 floats | m | finite | required |
| look_at | 3 floats | m | not the position | required |
| up | 3 floats | — | not along the view | [0, 0, 1] |
| fov_deg | float | ° | (0, 179]: the vertical field of view (three.js's `fov`) | required |
| width, height | int | px | [1, 4096] | required |
| lens_diameter_m | float | m | [0, 10]: a thin lens's aperture diameter; 0 or absent: a pinhole | 0 |
| focus_distance_m | float | m | > 0: the plane in focus, along the view from the eye | |look_at − position| |

The film is the plane at unit distance along the view; pixel (row, col), row 0 at the top, col 0 at the left, is
averaged uniformly over its area there. With a thin lens (``lens_diameter_m`` > 0) each pixel is also averaged
uniformly over the lens, a disk across the view at the eye: a ray leaves a point of the lens towards the point
where the pinhole ray of its film point meets the plane of focus (at ``focus_distance_m`` along the view), so a
Lambertian surface on that plane renders as the pinhole renders it, and one off it is blurred by the circle of
confusion (diameter D |z − f| / z on the plane at distance z); point-like lights in view are added through each
path's own lens point. Answered by paths from the eye (`tracer.transport.radiance`). The answer:
`tracer.sensors.views.LuminanceResult` with ``luminance`` and ``stderr`` (height, width) in cd/m².
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from tracer.errors import SimulationError
from tracer.optics.fields import BodyField, fields
from tracer.sensors.base import IlluminanceResult, Probe, vec3
from tracer.sensors.views import LuminanceResult, angle, check_fields, luminance_result, unit
from tracer.transport.radiance import PIXEL, ViewArrays

TYPE = "camera"
FORWARD_ONLY = False
OBSERVES = False
MAX_PIXELS_PER_SIDE = 4096
MAX_LENS_M = 10.0
FIELDS = fields(
    BodyField("position", "point", "The eye (the pinhole) [x, y, z], m."),
    BodyField("look_at", "point", "A point the view's centre passes through [x, y, z], m (not the position)."),
    BodyField("up", "direction", "Which way is up in the image (any length, not along the view); default "
              "[0, 0, 1].", required=False),
    BodyField("fov_deg", "number", "The vertical field of view (three.js's `fov`), degrees.", lo=0.0, hi=179.0,
              lo_open=True),
    BodyField("width", "count", "Pixels across (columns).", lo=1, hi=MAX_PIXELS_PER_SIDE),
    BodyField("height", "count", "Pixels down (rows; row 0 is the top).", lo=1, hi=MAX_PIXELS_PER_SIDE),
    BodyField("lens_diameter_m", "number", "A thin lens's aperture diameter, m (0 or absent: a pinhole, everything "
              "in focus).", required=False, lo=0.0, hi=MAX_LENS_M),
    BodyField("focus_distance_m", "number", "With a lens: the distance of the plane in focus along the view, m; "
              "default |look_at − position|.", required=False, lo=0.0, lo_open=True, hi=1e6))
EXAMPLE = {"type": "camera", "name": "room view", "position": [0.0, -3.0, 1.6], "look_at": [0.0, 0.0, 0.8],
           "up": [0.0, 0.0, 1.0], "fov_deg": 40.0, "width": 160, "height": 120}


def frame(body: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float, int, int]:
    """The camera's eye, unit forward, right and up axes, the film's half height at unit distance, width, height;
    `SimulationError` naming the field that is wrong."""
    check_fields(body, TYPE, FIELDS)
    eye = vec3(body.get("position"), "position")
    fwd = unit(vec3(body.get("look_at"), "look_at") - eye, "look_at − position")
    up = unit(vec3(body["up"] if body.get("up") is not None else [0.0, 0.0, 1.0], "up"), "up")
    right = np.cross(fwd, up)
    if not float(np.linalg.norm(right)) > 1e-6:
        raise SimulationError("up must not lie along the view (look_at − position)")
    right = right / np.linalg.norm(right)
    true_up = np.cross(right, fwd)
    fov = FIELDS["fov_deg"]
    half = math.tan(math.radians(angle(body, "fov_deg", fov.lo, fov.hi)) / 2.0)
    size: dict[str, int] = {}
    for name in ("width", "height"):
        v: Any = body.get(name)
        if isinstance(v, bool) or not isinstance(v, int | np.integer) or not 1 <= v <= MAX_PIXELS_PER_SIDE:
            raise SimulationError(f"{name} must be an integer number of pixels in [1, {MAX_PIXELS_PER_SIDE}], "
                                  f"got {v!r}")
        size[name] = int(v)
    return eye, fwd, right, true_up, half, size["width"], size["height"]


def lens(body: dict) -> tuple[float, float]:
    """(lens radius, focus distance) in metres: (0, 1) for a pinhole; `SimulationError` naming the field."""
    out = []
    for name in ("lens_diameter_m", "focus_distance_m"):
        v = body.get(name)
        f = FIELDS[name]
        if v is not None and (isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v)
                              or not (f.lo < v if f.lo_open else f.lo <= v) or not v <= f.hi):
            interval = f"({f.lo:g}, {f.hi:g}]" if f.lo_open else f"[{f.lo:g}, {f.hi:g}]"
            raise SimulationError(f"{name} must be a number of metres in {interval}, got {v!r}")
        out.append(v)
    diameter, focus = out
    if not diameter:
        return 0.0, 1.0
    if focus is None:
        focus = float(np.linalg.norm(vec3(body.get("look_at"), "look_at") - vec3(body.get("position"), "position")))
    return float(diameter) / 2.0, float(focus)


def check(body: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float, int, int]:
    """The body checked without a scene (`frame`, `lens`)."""
    out = frame(body)
    lens(body)
    return out


def probe(sim, body: dict) -> Probe:
    eye, fwd, right, up, half_h, w, h = frame(body)
    radius, focus = lens(body)
    half_w = half_h * w / h
    pw, ph = 2.0 * half_w / w, 2.0 * half_h / h
    rows, cols = np.divmod(np.arange(w * h), w)
    corner = (fwd[None, :] + (-half_w + cols * pw)[:, None] * right[None, :]
              + (half_h - rows * ph)[:, None] * up[None, :])
    k = w * h
    view = ViewArrays(np.full(k, PIXEL, np.int64), np.tile(eye, (k, 1)), np.tile(fwd, (k, 1)),
                      np.tile(right * pw, (k, 1)), np.tile(-up * ph, (k, 1)), np.ascontiguousarray(corner),
                      np.ones(k), np.full(k, pw * ph), np.full(k, radius), np.full(k, focus))
    return Probe(eye[None, :], fwd[None, :], view=view, keep={"shape": (h, w)})


def answer(sim, probe: Probe, res: IlluminanceResult) -> LuminanceResult:
    return luminance_result(sim, res, probe.keep["shape"])
