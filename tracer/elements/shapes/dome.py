"""A dome: the cap of the sphere of radius ``rs = (a^2 + h^2) / 2h`` centred at ``w' = h - rs``, over a round base of
radius ``a`` (a cap no taller than a hemisphere, ``h <= a``)."""

from __future__ import annotations

import math

import numpy as np

from tracer.elements.checks import ElementError, number
from tracer.elements.shapes.base import NO_FACES
from tracer.jit import njit

NAME = "dome"
FIELDS = {"radius_mm", "height_mm"}
LAYOUTS = ("grid", "hex", "density", "points")
ROUND = True
RIDGE = False
EXAMPLE = {"shape": NAME, "radius_mm": 0.25, "height_mm": 0.1}


def parse(f: dict) -> tuple[dict, float, float, float, np.ndarray]:
    a = number(f["radius_mm"], "feature.radius_mm")
    h = number(f["height_mm"], "feature.height_mm")
    if h > a:
        raise ElementError(f"feature.height_mm ({h:g}) must not exceed feature.radius_mm ({a:g}): a dome is a "
                           f"cap no taller than a hemisphere")
    return {"shape": NAME, "radius_mm": a, "height_mm": h}, a, h, (a * a + h * h) / (2.0 * h), NO_FACES


@njit(cache=True, error_model="numpy", _nrt=False)
def interval(a, h, rs, slope, P, cu, cv, ou, ov, ow, du, dv, dw):
    pu = ou - cu
    pv = ov - cv
    pw = ow - (h - rs)
    b = pu * du + pv * dv + pw * dw
    dd = du * du + dv * dv + dw * dw
    c = pu * pu + pv * pv + pw * pw - rs * rs
    disc = b * b - dd * c
    if disc < 0.0:
        return math.inf, -math.inf
    q = -b - math.copysign(math.sqrt(disc), b)   # the stable pair of roots
    if q == 0.0:
        return math.inf, -math.inf
    r0 = q / dd
    r1 = c / q
    return min(r0, r1), max(r0, r1)


@njit(cache=True, error_model="numpy", _nrt=False)
def covers(a, P, du, dv):
    return du * du + dv * dv <= a * a


@njit(cache=True, error_model="numpy", _nrt=False)
def surface(a, h, rs, slope, P, du, dv):
    wk = (h - rs) + math.sqrt(max(rs * rs - du * du - dv * dv, 0.0))
    return wk, du / rs, dv / rs, (wk - (h - rs)) / rs
