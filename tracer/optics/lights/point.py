"""Point light: isotropic emission from one point, Φ = 4π I.

============  ==========  =====  =========================================
Field         Type        Unit   Default
============  ==========  =====  =========================================
position      3 floats    m      required
intensity_cd  float ≥ 0   cd     exactly one of intensity_cd and flux_lm
flux_lm       float ≥ 0   lm     exactly one of intensity_cd and flux_lm
============  ==========  =====  =========================================

Parameter row: P_POS position, P_I0 intensity (cd), P_FLUX flux (lm), P_SOLID 4π.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tracer.jit import njit
from tracer.optics.fields import BodyField, fields
from tracer.optics.lights.base import (
    DELTA_POSITION,
    FLUX_LM,
    INTENSITY_CD,
    P_FLUX,
    P_I0,
    P_POS,
    P_SOLID,
    Packing,
    check_fields,
    intensity_and_flux,
    toward_point,
    vector_field,
)

NAME = "point"
FIELDS = fields(BodyField("position", "point", "[x, y, z], m (world, or the attached node's frame)."),
                INTENSITY_CD, FLUX_LM)
EXAMPLE = {"type": "point", "name": "bulb", "position": [0.0, 0.0, 2.0], "intensity_cd": 100.0}
EFFECTS = ()
FLAGS = DELTA_POSITION


@dataclass(frozen=True)
class Spec:
    """position (3,) m; intensity_cd (cd) and flux_lm (lm), one derived from the other."""

    position: np.ndarray
    intensity_cd: float
    flux_lm: float

    @classmethod
    def from_body(cls, body: dict, where: str) -> Spec:
        check_fields(body, where, NAME, FIELDS)
        position = vector_field(body, "position", where)
        i0, flux = intensity_and_flux(body, where, 4.0 * math.pi)
        return cls(position, i0, flux)


def pack(spec: Spec, j: int, out: Packing, where: str) -> float:
    """Fill row j; returns Φ (lm)."""
    row = out.par[j]
    row[P_POS:P_POS + 3] = spec.position
    row[P_I0], row[P_FLUX] = spec.intensity_cd, spec.flux_lm
    row[P_SOLID] = 4.0 * math.pi
    return spec.flux_lm


@njit(cache=True, _nrt=False, inline="always")
def sample(L, j, u0, u1, u2, u3, u4):
    """A uniform direction from the light's position: f = 1 (see base)."""
    p = L.par[j]
    z = 1.0 - 2.0 * u0
    r = math.sqrt(max(0.0, 1.0 - z * z))
    phi = 2.0 * math.pi * u1
    return p[0], p[1], p[2], r * math.cos(phi), r * math.sin(phi), z, 1.0, False, 0.0, 0.0, 0.0


@njit(cache=True, _nrt=False)
def connect(L, j, x, y, z, nx, ny, nz, u1, u2, u3):
    """E = I cosθ / d² at x (lx), a shadow ray to the position (see base)."""
    p = L.par[j]
    dx, dy, dz, d2, dist, cos_x = toward_point(p, x, y, z, nx, ny, nz)
    if cos_x <= 0.0:
        return 0.0, dx, dy, dz, 1.0
    return p[P_I0] * cos_x / d2, dx, dy, dz, 1.0
