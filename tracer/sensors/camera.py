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

import dataclasses
import hashlib
import math
from typing import Any

import numpy as np

from tracer.errors import SimulationError
from tracer.optics.fields import BodyField, fields
from tracer.sensors.base import IlluminanceResult, Probe, vec3
from tracer.sensors.views import LuminanceResult, angle, check_fields, luminance_result, merge_pilots, unit
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
    return band_probe(sim, body, 0, None)


def band_probe(sim, body: dict, row0: int, row1: int | None) -> Probe:
    """The probe of the camera's rows ``row0`` … ``row1`` − 1 (None: to the bottom): the same film, eye and lens, its
    pixels those rows' (a camera of its own, ``row1 − row0`` rows high, whose film window is that band)."""
    eye, fwd, right, up, half_h, w, h_all = frame(body)
    radius, focus = lens(body)
    row1 = h_all if row1 is None else row1
    if not 0 <= row0 < row1 <= h_all:
        raise SimulationError(f"rows {row0}..{row1} are not a band of a camera {h_all} rows high")
    h = row1 - row0
    half_w = half_h * w / h_all
    pw, ph = 2.0 * half_w / w, 2.0 * half_h / h_all
    rows, cols = np.divmod(np.arange(w * h), w)
    rows = rows + row0
    corner = (fwd[None, :] + (-half_w + cols * pw)[:, None] * right[None, :]
              + (half_h - rows * ph)[:, None] * up[None, :])
    k = w * h
    view = ViewArrays(np.full(k, PIXEL, np.int64), np.tile(eye, (k, 1)), np.tile(fwd, (k, 1)),
                      np.tile(right * pw, (k, 1)), np.tile(-up * ph, (k, 1)), np.ascontiguousarray(corner),
                      np.ones(k), np.full(k, pw * ph), np.full(k, radius), np.full(k, focus))
    return Probe(eye[None, :], fwd[None, :], view=view, keep={"shape": (h, w)})


def answer(sim, probe: Probe, res: IlluminanceResult) -> LuminanceResult:
    return luminance_result(sim, res, probe.keep["shape"])


def band_rows(width: int, height: int, max_pixels: int) -> list[tuple[int, int]]:
    """Bands of whole rows, ``(row0, row1)``, each of at most `max_pixels` pixels (at least one row, so a row wider
    than `max_pixels` is a band of its own: the caller bounds the width), as even as the rows allow."""
    per = max(1, min(height, max_pixels // width))
    n = -(-height // per)
    edges = [round(i * height / n) for i in range(n + 1)]
    return [(edges[i], edges[i + 1]) for i in range(n)]


def band_seed(seed: int, band: int) -> int:
    """The seed of band `band`: the query's own for the first (an image of one band is the image it always was), a
    hash of (seed, band) for the others, so no two bands draw the same random numbers for their pixels."""
    if band == 0:
        return int(seed)
    digest = hashlib.sha256(f"lumenlink camera band {int(seed)} {band}".encode()).digest()
    return int.from_bytes(digest[:8], "little") >> 1


STOP_ORDER = ("cancelled", "max_seconds", "max_photons", "target_relative_error")   # the image's: its bands' first


def run_in_bands(sim, body: dict, max_pixels: int, query: Any, progress=None, cancel=None) -> LuminanceResult:
    """A camera of more than `max_pixels` pixels, traced a band of rows at a time (`band_rows`), each band a query
    of its own (`tracer.simulate.Simulation.measure`: `query`, a `tracer.transport.query.Query`, with the band's
    budget and seed), assembled into the image `Simulation.run` answers: the same fields and shape.

    Each pixel's value and standard error are its band's (batch means over that band's own batches: as honest as
    one band's); each band draws from its own seed (`band_seed`). The budget is the image's: each band gets its
    share of `max_photons` by its pixels, and of the seconds left by its pixels among those left; a
    target relative error holds in every band (with the "worst" scope: in every pixel of the image). `photons`,
    `batches`, `rejected`, the counters and `compile_seconds` add up; `seconds` is the wall time of all the bands;
    `stop_reason` the bands' first in `STOP_ORDER`; `cost` is the image's (`cost_of` over all its pixels).
    `progress(photons, worst_relative_error, seconds)` counts the bands already done in."""
    import time

    from tracer.sensors.views import luminance_result
    from tracer.transport.estimate import cost_of
    from tracer.transport.rounds import ViewBins

    _, _, _, _, _, w, h = check(body)
    bands = band_rows(w, h, int(max_pixels))
    rules = query.budget.stop_rules()   # the image's (`DEFAULT_MAX_SECONDS` where it states none)
    max_seconds, max_photons = rules.max_seconds, rules.max_photons
    t0 = time.perf_counter()
    done_photons = 0
    parts: list[Any] = []
    for b, (r0, r1) in enumerate(bands):
        share = (r1 - r0) / (h - r0)          # of the pixels left
        left = None if max_seconds is None else max(1e-3, (max_seconds - (time.perf_counter() - t0)) * share)
        photons = None if max_photons is None else max(1, int(max_photons) * (r1 - r0) * w // (w * h))

        def report(p, rel, sec, _done=done_photons):
            if progress is not None:
                progress(_done + p, rel, time.perf_counter() - t0 if p else sec)

        band = dataclasses.replace(query, budget=dataclasses.replace(rules, max_seconds=left, max_photons=photons),
                                   seed=band_seed(query.seed, b))
        _, res = sim.measure(lambda s, bd, r0=r0, r1=r1: band_probe(s, bd, r0, r1), body, band, report, cancel)
        parts.append(res)
        done_photons += int(res.photons)
    first = parts[0]
    counters: dict[str, int] = {}
    for r in parts:
        for k, v in r.counters.items():
            counters[k] = counters.get(k, 0) + int(v)
    reasons = {r.stop_reason for r in parts}
    combined = ViewBins(np.concatenate([r.lux for r in parts]), np.concatenate([r.stderr for r in parts]),
                        photons=sum(int(r.photons) for r in parts), seconds=time.perf_counter() - t0,
                        effects=first.effects, estimator=first.estimator,
                        stop_reason=next(x for x in STOP_ORDER if x in reasons) if reasons <= set(STOP_ORDER)
                        else first.stop_reason,
                        batches=sum(int(r.batches) for r in parts), rejected=sum(int(r.rejected) for r in parts),
                        counters=counters, compile_seconds=sum(float(r.compile_seconds) for r in parts),
                        through_specular=np.concatenate([np.asarray(r.through_specular) for r in parts]),
                        light_traced=any(r.light_traced for r in parts),
                        area_pilot=merge_pilots([r.area_pilot for r in parts]))
    combined.backend, combined.effect_reasons = first.backend, first.effect_reasons
    combined.cost = cost_of(combined.lux, combined.stderr, combined.photons,
                            combined.seconds - combined.compile_seconds)
    out = luminance_result(sim, combined, (h, w))
    out.bands = len(bands)
    return out
