"""What the luminance kinds (`luminance`, `camera`) share: their answer, and what it says paths from the eye missed.

Not a kind itself (it has no ``TYPE``). Units: luminance L_v in cd/m² = lm/(m² sr), angles in degrees on the wire.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from tracer.errors import SimulationError
from tracer.optics.lights.base import DELTA_DIRECTION, DELTA_POSITION
from tracer.optics.lights.dispatch import flags_of
from tracer.sensors.base import IlluminanceResult, Readout

#: what ran, as every luminance answer states it (`tracer.transport.radiance`)
STRATEGY = ("paths from the eye: next-event estimation to every light at diffuse surfaces (one light a vertex, "
            "picked by flux), multiple importance sampling (power heuristic) with BSDF sampling where a light has "
            "area, specular chains followed through mirrors and glass, Russian roulette after 3 diffuse bounces; "
            "point-like lights in view added exactly")
LIGHT_TRACING = ("; light tracing where the scene has what the paths from the eye miss or find badly (a specular "
                 "surface: photons of every light through it, a caustic, an area light behind glass; a beam): each "
                 "diffuse vertex of a photon whose first bounce was specular (any photon of a beam) joined to the "
                 "eye, the paths split so that none is counted by both; both unbiased")
BODY_COMMON = frozenset({"type", "id", "name", "attached_to"})   # kept by the service, ignored here


@dataclass
class LuminanceResult(Readout):
    """Luminance seen by a meter (scalars) or a camera ((height, width) arrays, top row first).

    luminance, stderr : cd/m² — the mean luminance over the meter's cone or each pixel, and its standard error
        (batch means over independent batches).
    cost : dict — what tighter errors would cost (`tracer.transport.estimate.cost_of`), over the pixels.
    strategy : str — the estimator that ran, in words (`STRATEGY`, with `LIGHT_TRACING` where it ran too).
    through_specular : float or (height, width) — share of the view's paths whose view ray went on through a mirror
        or glass before any diffuse surface.
    unreachable : dict or None — the light paths from the eye cannot find, where the scene has them (None: nothing
        is missing): ``{"lights": [light indices], "why": str, "through_specular": max share over the views,
        "caustic_paths": paths that met a specular surface after a diffuse one}``. The value then lacks that light.
    bands : int — the bands of rows a camera was traced in (`tracer.sensors.camera.run_in_bands`); 1: one query.
    """

    luminance: Any
    stderr: Any
    cost: dict | None = None
    strategy: str = STRATEGY
    through_specular: Any = None
    unreachable: dict | None = None
    bands: int = 1


def unreachable(sim, share: np.ndarray, caustic_paths: int, light_traced: bool = False) -> dict | None:
    """What the paths from the eye (and light tracing, where it ran: `light_traced`) could not find in this scene
    (see `LuminanceResult.unreachable`)."""
    bodies = sim.light_bodies
    flags = [flags_of(b) for b in bodies]
    beams = [j for j, f in enumerate(flags) if f & DELTA_DIRECTION]   # no shadow ray reaches them
    point_like = [j for j, f in enumerate(flags) if f == DELTA_POSITION]
    top = float(np.max(share)) if share.size else 0.0
    lights: list[int] = []
    why = []
    if light_traced:
        # light tracing joins diffuse vertices to the eye: what is missing is a delta light reached only through a
        # specular chain that ends at the eye (a lamp, a caustic or a beam seen in a mirror or through glass)
        if top > 0.0 and (point_like or beams):
            lights += point_like + beams
            why.append(f"point-like or collimated light(s) {sorted(point_like + beams)} seen through a specular "
                       f"chain from the eye (in a mirror, through glass: {top:.0%} of the paths of the most affected "
                       f"view went on through one) cannot be reached by paths from the eye nor joined by light "
                       f"tracing: that light (the lamp, or a caustic, seen in the mirror) is missing")
    else:
        if beams:
            lights += beams
            why.append(f"collimated light(s) {beams} cannot be sampled from a point (no shadow ray finds a beam): "
                       f"their light is missing from every view")
        if point_like and (top > 0.0 or caustic_paths > 0):
            lights += point_like
            why.append(f"point-like light(s) {point_like} seen through a specular chain (in a mirror, through glass: "
                       f"{top:.0%} of the paths of the most affected view went on through one), or lighting a diffuse "
                       f"surface only through one (a caustic: {caustic_paths} paths met a specular surface after a "
                       f"diffuse one), cannot be reached by paths from the eye: that light is missing")
    if not lights:
        return None
    return {"lights": sorted(set(lights)), "why": "; ".join(why), "through_specular": top,
            "caustic_paths": int(caustic_paths)}


def merge_pilots(pilots: list[dict | None]) -> dict | None:
    """The area-light pilots of a camera's bands (`tracer.transport.rounds.area_light_pilot`) as one: photons and
    joins summed, traced where any band traced."""
    ran = [p for p in pilots if p is not None]
    if not ran:
        return None
    return {"photons": sum(p["photons"] for p in ran), "joined": sum(p["joined"] for p in ran),
            "eye_finds": sum(p["eye_finds"] for p in ran), "share": max(p["share"] for p in ran),
            "traced": any(p["traced"] for p in ran),
            "per_batch": max(p["per_batch"] for p in ran)}


def pilot_words(pilot: dict | None) -> str:
    """What the area-light pilot found, for the answer's strategy ('' where none ran)."""
    if pilot is None:
        return ""
    how = (f"traced ({pilot['per_batch']:,} photons a batch)" if pilot["traced"] else
           "left to the paths from the eye")
    return (f"; area lights {how}: a pilot of {pilot['photons']:,} of their photons had {pilot['joined']:,} diffuse "
            f"vertices joined to the views, where its paths from the eye found {pilot['eye_finds']:,} of those paths; "
            f"{pilot['share']:.1%} of the light seen came by light tracing")


def luminance_result(sim, res: IlluminanceResult, shape: tuple[int, ...] | None) -> LuminanceResult:
    """The raw view bins (`tracer.transport.rounds.ViewBins`) as a `LuminanceResult`: scalars where `shape` is None
    (a meter), else arrays of `shape`."""
    share = getattr(res, "through_specular", None)
    share = np.zeros_like(res.lux) if share is None else np.asarray(share)

    def shaped(a: np.ndarray) -> Any:
        return float(a[0]) if shape is None else a.reshape(shape)

    traced = bool(getattr(res, "light_traced", False))
    return LuminanceResult(**res.readout(), luminance=shaped(res.lux), stderr=shaped(res.stderr), cost=res.cost,
                           strategy=STRATEGY + (LIGHT_TRACING if traced else "") + pilot_words(
                               getattr(res, "area_pilot", None)), through_specular=shaped(share),
                           unreachable=unreachable(sim, share, int(res.counters.get("caustic_paths", 0)), traced))


def check_fields(body: dict, kind: str, fields: Any) -> None:
    """`SimulationError` naming any field of `body` a `kind` sensor does not take (`fields`: its names)."""
    extra = set(body) - set(fields) - BODY_COMMON
    if extra:
        raise SimulationError(f"unknown field(s) {sorted(extra)} for a {kind!r} sensor; it takes {sorted(fields)}")


def angle(body: dict, name: str, lo: float, hi: float, default: float | None = None) -> float:
    """body[name] as degrees in (lo, hi]; `default` where absent; `SimulationError` naming the field otherwise."""
    v = body.get(name)
    if v is None and default is not None:
        return default
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or not lo < v <= hi:
        raise SimulationError(f"{name} must be a number of degrees in ({lo:g}, {hi:g}], got {v!r}")
    return float(v)


def unit(v: np.ndarray, name: str) -> np.ndarray:
    """v / |v|; `SimulationError` naming the field where v is the zero vector."""
    n = float(np.linalg.norm(v))
    if not n > 0.0:
        raise SimulationError(f"{name} must not be the zero vector")
    return v / n
