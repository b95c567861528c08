"""A prism: a ridge ``|u - cu| + slope w' <= a`` along v across the whole support, its base ``2a`` wide and its apex
angle given (``h = a / tan(apex / 2)``)."""

from __future__ import annotations

import math

import numpy as np

from tracer.elements.checks import ElementError, number
from tracer.elements.shapes.base import NO_FACES, half_space
from tracer.jit import njit

NAME = "prism"
FIELDS = {"base_mm", "apex_deg"}
LAYOUTS = ("grid",)
ROUND = False
RIDGE = True
EXAMPLE = {"shape": NAME, "base_mm": 0.05, "apex_deg": 90.0}


def parse(f: dict) -> tuple[dict, float, float, float, np.ndarray]:
    b = number(f["base_mm"], "feature.base_mm")
    apex = number(f["apex_deg"], "feature.apex_deg", hi=179.0)
    if apex < 1.0:
        raise ElementError(f"feature.apex_deg must be in [1, 179], got {apex!r}")
    h = b / 2.0 / math.tan(math.radians(apex) / 2.0)
    return {"shape": NAME, "base_mm": b, "apex_deg": apex}, b / 2.0, h, 0.0, NO_FACES


@njit(cache=True, error_model="numpy", _nrt=False)
def interval(a, h, rs, slope, P, cu, cv, ou, ov, ow, du, dv, dw):
    lo, hi, _, _ = half_space(1.0, 0.0, slope, a + cu, ou, ov, ow, du, dv, dw, -math.inf, math.inf)
    lo, hi, _, _ = half_space(-1.0, 0.0, slope, a - cu, ou, ov, ow, du, dv, dw, lo, hi)
    return lo, hi


@njit(cache=True, error_model="numpy", _nrt=False)
def covers(a, P, du, dv):
    return abs(du) <= a


@njit(cache=True, error_model="numpy", _nrt=False)
def surface(a, h, rs, slope, P, du, dv):
    norm = math.sqrt(1.0 + slope * slope)
    return (a - abs(du)) / slope, math.copysign(1.0, du) / norm, 0.0, slope / norm
