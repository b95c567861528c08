"""A corner cube: three mutually perpendicular faces meeting at the apex ``w' = h`` above the centre, its axis along
w: ``d_k . (q - c) + w' / sqrt(2) <= h / sqrt(2)`` for the unit directions ``d_k`` of the plane at -90, 30 and 150
degrees from u (each face's normal ``(sqrt(2/3) d_k, 1/sqrt(3))``, so the three are orthogonal); its base an
equilateral triangle of side ``s`` (a vertex towards +v), inradius ``rs = h / sqrt(2)``, circumradius ``a = 2 rs``,
``h = s / sqrt(6)`` (the "triangular" corner cube of Eckhardt, Appl. Opt. 10, 1559 (1971)): a retroreflector."""

from __future__ import annotations

import math

import numpy as np

from tracer.elements.checks import number
from tracer.elements.shapes.base import C30, NO_FACES, S2, half_space
from tracer.jit import njit

NAME = "corner_cube"
FIELDS = {"side_mm"}
LAYOUTS = ("grid", "hex", "density", "points", "triangular")
ROUND = True
RIDGE = False
EXAMPLE = {"shape": NAME, "side_mm": 0.3}


def parse(f: dict) -> tuple[dict, float, float, float, np.ndarray]:
    side = number(f["side_mm"], "feature.side_mm")
    a, h, rs = side / math.sqrt(3.0), side / math.sqrt(6.0), side / (2.0 * math.sqrt(3.0))
    return {"shape": NAME, "side_mm": side}, a, h, rs, NO_FACES


@njit(cache=True, error_model="numpy", _nrt=False)
def interval(a, h, rs, slope, P, cu, cv, ou, ov, ow, du, dv, dw):
    c = h / S2
    lo, hi, _, _ = half_space(0.0, -1.0, 1.0 / S2, -cv + c, ou, ov, ow, du, dv, dw, -math.inf, math.inf)
    lo, hi, _, _ = half_space(C30, 0.5, 1.0 / S2, C30 * cu + 0.5 * cv + c, ou, ov, ow, du, dv, dw, lo, hi)
    lo, hi, _, _ = half_space(-C30, 0.5, 1.0 / S2, -C30 * cu + 0.5 * cv + c, ou, ov, ow, du, dv, dw, lo, hi)
    return lo, hi


@njit(cache=True, error_model="numpy", _nrt=False)
def covers(a, P, du, dv):
    ri = 0.5 * a
    return -dv <= ri and C30 * du + 0.5 * dv <= ri and -C30 * du + 0.5 * dv <= ri


@njit(cache=True, error_model="numpy", _nrt=False)
def surface(a, h, rs, slope, P, du, dv):
    p0 = -dv
    p1 = C30 * du + 0.5 * dv
    p2 = -C30 * du + 0.5 * dv
    s23 = math.sqrt(2.0 / 3.0)
    if p0 >= p1 and p0 >= p2:
        top, ku, kv = p0, 0.0, -s23
    elif p1 >= p2:
        top, ku, kv = p1, s23 * C30, s23 * 0.5
    else:
        top, ku, kv = p2, -s23 * C30, s23 * 0.5
    return h - S2 * top, ku, kv, 1.0 / math.sqrt(3.0)
