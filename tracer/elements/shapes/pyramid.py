"""A pyramid: ``|u - cu| + slope w' <= a`` and ``|v - cv| + slope w' <= a`` (``slope = a / h``), a square base of
side ``2a`` with its sides along u and v."""

from __future__ import annotations

import math

import numpy as np

from tracer.elements.checks import number
from tracer.elements.shapes.base import NO_FACES, half_space
from tracer.jit import njit

NAME = "pyramid"
FIELDS = {"base_mm", "height_mm"}
LAYOUTS = ("grid", "density", "points")
ROUND = False
RIDGE = False
EXAMPLE = {"shape": NAME, "base_mm": 0.2, "height_mm": 0.08}


def parse(f: dict) -> tuple[dict, float, float, float, np.ndarray]:
    b = number(f["base_mm"], "feature.base_mm")
    h = number(f["height_mm"], "feature.height_mm")
    return {"shape": NAME, "base_mm": b, "height_mm": h}, b / 2.0, h, 0.0, NO_FACES


@njit(cache=True, error_model="numpy", _nrt=False)
def interval(a, h, rs, slope, P, cu, cv, ou, ov, ow, du, dv, dw):
    lo, hi, _, _ = half_space(1.0, 0.0, slope, a + cu, ou, ov, ow, du, dv, dw, -math.inf, math.inf)
    lo, hi, _, _ = half_space(-1.0, 0.0, slope, a - cu, ou, ov, ow, du, dv, dw, lo, hi)
    lo, hi, _, _ = half_space(0.0, 1.0, slope, a + cv, ou, ov, ow, du, dv, dw, lo, hi)
    lo, hi, _, _ = half_space(0.0, -1.0, slope, a - cv, ou, ov, ow, du, dv, dw, lo, hi)
    return lo, hi


@njit(cache=True, error_model="numpy", _nrt=False)
def covers(a, P, du, dv):
    return abs(du) <= a and abs(dv) <= a


@njit(cache=True, error_model="numpy", _nrt=False)
def surface(a, h, rs, slope, P, du, dv):
    norm = math.sqrt(1.0 + slope * slope)
    if abs(du) >= abs(dv):
        return (a - abs(du)) / slope, math.copysign(1.0, du) / norm, 0.0, slope / norm
    return (a - abs(dv)) / slope, 0.0, math.copysign(1.0, dv) / norm, slope / norm
