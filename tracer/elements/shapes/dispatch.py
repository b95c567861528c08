"""The feature shapes' registration: the one place that lists them and switches on a shape id.

A shape's id is its position in `KINDS` (a library file stores it: append, never reorder). Adding a shape: its
module (see `base`) and its entry at the end of `KINDS`; the switches below are written out from `KINDS`
(`tracer.jit.kind_switch`)."""

from __future__ import annotations

from tracer.elements.shapes import corner_cube, dome, mesh, prism, pyramid
from tracer.jit import kind_switch

KINDS = (dome, pyramid, prism, corner_cube, mesh)
SHAPE_OF_NAME = {module.NAME: k for k, module in enumerate(KINDS)}

shape_interval = kind_switch(
    "shape_interval", "shape, a, h, rs, slope, P, cu, cv, ou, ov, ow, du, dv, dw", "shape",
    {k: m.interval for k, m in enumerate(KINDS)}, "(1.0, 0.0)",
    passes="a, h, rs, slope, P, cu, cv, ou, ov, ow, du, dv, dw",
    doc="The ray's interval inside the sides of feature `shape` centred at (cu, cv); empty where it misses.",
    cache=True, error_model="numpy", _nrt=False)

shape_covers = kind_switch(
    "shape_covers", "shape, a, P, du, dv", "shape", {k: m.covers for k, m in enumerate(KINDS)}, "False",
    passes="a, P, du, dv",
    doc="Whether the base of feature `shape` covers the plane point (du, dv) from its centre.",
    cache=True, error_model="numpy", _nrt=False)

shape_surface = kind_switch(
    "shape_surface", "shape, a, h, rs, slope, P, du, dv", "shape", {k: m.surface for k, m in enumerate(KINDS)},
    "(0.0, 0.0, 0.0, 1.0)", passes="a, h, rs, slope, P, du, dv",
    doc="(w', nu, nv, nw'): the height of feature `shape` above (du, dv) from its centre and its outward normal.",
    cache=True, error_model="numpy", _nrt=False)
