"""``retarder``: a thin waveplate that delays the field along its slow axis behind the fast one.

| field | type | unit | range | default |
| --- | --- | --- | --- | --- |
| fast_axis | [x, y, z], in the node's frame | — | not zero | required |
| retardance_deg | float: the phase delay δ of the slow axis | degrees | [0, 360] | required |
| transmittance | float | fraction | (0, 1] | 1 |

Mueller matrix in the frame whose x axis is the fast axis: T [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, cos δ, −sin δ],
[0, 0, sin δ, cos δ]] (Jones diag(1, e^{−iδ}), `tracer.optics.polarization`): a quarter-wave plate (δ = 90°)
turns linear light at 45° to its axis into circular light, a half-wave plate mirrors linear light about it.
The retardance is the same at every wavelength and angle (an ideal achromatic plate); the axis is taken
onto the sheet's plane, then across the photon's direction. A photon crosses it straight on (absorbed with
probability 1 − T); it reflects nothing and acts alike from both sides. Effects: `polarization`.
Backward estimator: no.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from tracer.jit import njit
from tracer.optics.elements.base import parse_axis, sheet_axis
from tracer.optics.polarization import ON, across, apply_interface, rotate_into
from tracer.optics.surfaces.base import ABSORBED, CONTINUES, SPECULAR, TRANSMITS, bounds
from tracer.rng import uniform

NAME = "retarder"
FLAGS = SPECULAR | TRANSMITS


@dataclass(frozen=True)
class Spec:
    """Fast axis (node frame), retardance δ in degrees, transmittance."""

    fast_axis: tuple[float, float, float] = field(metadata={
        "parse": parse_axis, "doc": "fast axis [x, y, z] in the node's frame (in the sheet's plane)"})
    retardance_deg: float = field(metadata=bounds(0.0, 360.0, doc="retardance δ, degrees (90: a quarter-wave plate)"))
    transmittance: float = field(default=1.0, metadata=bounds(0.0, 1.0, lo_open=True, doc="transmittance, fraction"))


def row(spec: Spec) -> np.ndarray:
    return np.array([*spec.fast_axis, math.radians(spec.retardance_deg), spec.transmittance])


def effects(spec: Spec) -> tuple[str, ...]:
    return ("polarization",)


def diffuse_only(spec: Spec) -> bool:
    return False



@njit(cache=True, error_model="numpy", _nrt=False)
def scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim, lam, pol):
    t = M.par[inst, 4]
    if uniform(key, dim) >= t:
        return ABSORBED, dx, dy, dz, 0.0, depth, dim + 1
    if pol[ON] != 0.0:
        wx, wy, wz = sheet_axis(sa, inst, M.par[inst, 0], M.par[inst, 1], M.par[inst, 2], ngx, ngy, ngz)
        ok, ax, ay, az = across(dx, dy, dz, wx, wy, wz)
        if ok:
            rotate_into(pol, dx, dy, dz, ax, ay, az)
            delta = M.par[inst, 3]
            apply_interface(pol, 1.0, 1.0, math.cos(delta), math.sin(delta))
    return CONTINUES, dx, dy, dz, 1.0, depth, dim + 1
