"""The contract of a feature shape: what a module in this folder defines, and what the shapes share.

A feature's solid ``K`` sits on the support plane at its centre ``(cu, cv)``, in ``w' = sign * w`` (+1 a bump, -1 a
pit), between ``w' = 0`` and its height ``h``; lengths in mm, in the element's frame (`tracer.elements.features`).
Each shape is four numbers, packed once (`tracer.elements.support`): ``a`` its half base (a radius for a round base),
``h`` its height, ``rs`` a length of its own (a dome's sphere radius, a corner cube's inradius) and ``slope = a / h``;
and its face planes ``P`` (K, 4) float64, rows ``(nu, nv, nw', c)``: ``K`` is where ``n . (p - centre) <= c`` for
every row (a mesh's faces; empty, `NO_FACES`, for a shape given by its numbers alone).

A shape module defines:

- ``NAME``: the body's ``"shape"``; ``FIELDS``: its other keys, all required; ``EXAMPLE``: a body of it;
- ``LAYOUTS``: the layouts it takes (of ``"grid"``, ``"hex"``, ``"density"``, ``"points"``, ``"triangular"``: a
  triangle-based shape only, every other feature turned 180 degrees);
- ``ROUND``: whether its base is round (two features overlap closer than ``2a`` apart, Euclidean) or square (in each
  axis); ``RIDGE``: whether it runs across the whole support along v (one row; its pitch along v is free);
- ``parse(feature) -> (canonical body, a, h, rs, P)``, raising `tracer.elements.checks.ElementError` naming the
  field (its keys are checked against ``FIELDS`` before);
- three jitted functions the inner tracer calls through `dispatch`'s switches (plain arithmetic, as numba compiles):
  ``interval(a, h, rs, slope, P, cu, cv, ou, ov, ow, du, dv, dw) -> (lo, hi)``: the ray's parameter interval inside
  ``K``'s sides (its half-spaces or its sphere; the base plane is cut by the caller), empty (``lo >= hi``) where it
  misses; ``covers(a, P, du, dv) -> bool``: whether its base covers the plane point ``(du, dv)`` from its centre;
  ``surface(a, h, rs, slope, P, du, dv) -> (w', nu, nv, nw')``: the height of ``K`` above the plane point
  ``(du, dv)`` from its centre and ``K``'s outward unit normal there.

Adding a shape: its module here and its entry at the end of `dispatch.KINDS` (an id is a position: a library file
stores it).
"""

from __future__ import annotations

import math

import numpy as np

from tracer.jit import njit

S2 = math.sqrt(2.0)
C30 = math.sqrt(3.0) / 2.0      # cos 30 degrees
NO_FACES = np.zeros((0, 4))     # the face planes of a shape given by its numbers alone


@njit(cache=True, error_model="numpy", inline="always")
def half_space(nu, nv, nw, c, ou, ov, ow, du, dv, dw, lo, hi):
    """Bound ``(lo, hi)`` by the half-space ``n . p <= c`` along the ray; also whether each end moved."""
    nd = nu * du + nv * dv + nw * dw
    no = nu * ou + nv * ov + nw * ow
    if nd == 0.0:
        if no > c:
            return 1.0, 0.0, False, False
        return lo, hi, False, False
    t = (c - no) / nd
    if nd > 0.0:
        if t < hi:
            return lo, t, False, True
        return lo, hi, False, False
    if t > lo:
        return t, hi, True, False
    return lo, hi, False, False
