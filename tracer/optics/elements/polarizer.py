"""``polarizer``: a thin linear polarizer sheet (a polarizing film, a wire grid taken as thin).

| field | type | unit | range | default |
| --- | --- | --- | --- | --- |
| axis | [x, y, z], the transmission axis in the node's frame | — | not zero | required |
| transmittance | float | fraction | (0, 1] | 1 |
| extinction_ratio | float: k1 / k2 | — | [1, 1e15] | ideal (k2 = 0) |

The principal transmittances are k1 = `transmittance` (light polarized along the axis) and k2 = k1 /
`extinction_ratio` (across it); unpolarized light passes (k1 + k2) / 2. Mueller matrix in the frame whose x
axis is the transmission axis: ½ [[k1+k2, k1−k2, 0, 0], [k1−k2, k1+k2, 0, 0], [0, 0, 2√(k1k2), 0],
[0, 0, 0, 2√(k1k2)]] (`tracer.optics.polarization.apply_interface`). The axis is taken onto the sheet's plane
at the hit, then across the photon's direction: at oblique incidence the sheet passes the field along
that projection (the usual thin-sheet model; no angle dependence of k1, k2). A photon crosses it straight
on or is absorbed; the sheet reflects nothing and acts alike from both sides. Effects: `polarization`.
Backward estimator: no.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from tracer.jit import njit
from tracer.optics.elements.base import parse_axis, sheet_axis
from tracer.optics.polarization import ON, across, apply_interface, interface_power, rotate_into
from tracer.optics.surfaces.base import ABSORBED, CONTINUES, SPECULAR, TRANSMITS, bounds
from tracer.rng import uniform

NAME = "polarizer"
FLAGS = SPECULAR | TRANSMITS


@dataclass(frozen=True)
class Spec:
    """Transmission axis (node frame), principal transmittance k1 and extinction ratio k1 / k2."""

    axis: tuple[float, float, float] = field(metadata={
        "parse": parse_axis, "doc": "transmission axis [x, y, z] in the node's frame (in the sheet's plane)"})
    transmittance: float = field(default=1.0, metadata=bounds(
        0.0, 1.0, lo_open=True, doc="k1: transmittance for light polarized along the axis, fraction"))
    extinction_ratio: float | None = field(default=None, metadata=bounds(
        1.0, 1e15, doc="k1 / k2, a ratio (absent: an ideal polarizer, k2 = 0)"))


def row(spec: Spec) -> np.ndarray:
    k2 = 0.0 if spec.extinction_ratio is None else spec.transmittance / spec.extinction_ratio
    return np.array([*spec.axis, spec.transmittance, k2])


def effects(spec: Spec) -> tuple[str, ...]:
    return ("polarization",)


def diffuse_only(spec: Spec) -> bool:
    return False



@njit(cache=True, error_model="numpy", _nrt=False)
def scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim, lam, pol):
    k1, k2 = M.par[inst, 3], M.par[inst, 4]
    if pol[ON] == 0.0:   # not carried (never in a scene with a polarizer, which calls for `polarization`)
        passed = 0.5 * (k1 + k2)
    else:
        wx, wy, wz = sheet_axis(sa, inst, M.par[inst, 0], M.par[inst, 1], M.par[inst, 2], ngx, ngy, ngz)
        ok, ax, ay, az = across(dx, dy, dz, wx, wy, wz)
        if ok:
            rotate_into(pol, dx, dy, dz, ax, ay, az)
        passed = interface_power(pol, k1, k2)
    if uniform(key, dim) >= passed:
        return ABSORBED, dx, dy, dz, 0.0, depth, dim + 1
    if pol[ON] != 0.0:
        apply_interface(pol, k1, k2, math.sqrt(k1 * k2), 0.0)
    return CONTINUES, dx, dy, dz, 1.0, depth, dim + 1
