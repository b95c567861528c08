"""Spot light: a point emitting into a cone about its axis.

I(θ) = I0 for θ ≤ cone − falloff and a smoothstep in cosθ down to 0 at θ = cone (θ from the axis);
Φ = 2π I0 [(1 − cos θi) + (cos θi − cos θo)/2] with θo = cone, θi = cone − falloff.

============  ==============  =====  =========================================
Field         Type            Unit   Default
============  ==============  =====  =========================================
position      3 floats        m      required
direction     3 floats ≠ 0    —      required (the axis; normalised)
cone_deg      float (0, 180]  °      required (half-angle where I reaches 0)
falloff_deg   float [0, cone] °      0
intensity_cd  float ≥ 0       cd     exactly one of intensity_cd and flux_lm
flux_lm       float ≥ 0       lm     exactly one of intensity_cd and flux_lm
============  ==============  =====  =========================================

Parameter row: P_POS position, P_AXIS unit axis, P_T, P_B a frame about it, P_COS_OUT cos θo,
P_COS_IN cos θi, P_I0 I0 (cd), P_FLUX flux (lm), P_SOLID ∫ I/I0 dΩ (sr).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tracer.jit import njit
from tracer.optics.fields import BodyField, fields
from tracer.optics.frames import onb
from tracer.optics.lights.base import (
    DELTA_POSITION,
    FLUX_LM,
    INTENSITY_CD,
    P_AXIS,
    P_B,
    P_COS_IN,
    P_COS_OUT,
    P_FLUX,
    P_I0,
    P_POS,
    P_SOLID,
    P_T,
    LightError,
    Packing,
    check_fields,
    field_value,
    in_light_frame,
    intensity_and_flux,
    toward_point,
    vector_field,
)

NAME = "spot"
FIELDS = fields(
    BodyField("position", "point", "[x, y, z], m (world, or the attached node's frame)."),
    BodyField("direction", "direction", "The cone's axis (any length, not zero; dimensionless)."),
    BodyField("cone_deg", "number", "Half-angle of the cone, degrees.", lo=0.0, hi=180.0, lo_open=True),
    BodyField("falloff_deg", "number", "Half-angle, degrees, beyond which the intensity falls to 0 at cone_deg (0: "
              "a hard edge); default 0.", required=False, lo=0.0, hi=180.0),
    INTENSITY_CD, FLUX_LM)
EXAMPLE = {"type": "spot", "name": "downlight", "position": [1.0, 0.0, 2.5], "direction": [0.0, 0.0, -1.0],
           "cone_deg": 30.0, "falloff_deg": 25.0, "flux_lm": 800.0, "spectrum": {"type": "blackbody", "kelvin": 3000.0}}
EFFECTS = ()
FLAGS = DELTA_POSITION


def spot_solid_angle(cos_out: float, cos_in: float) -> float:
    """∫ f dΩ of the spot profile (1 inside, smoothstep in cosθ across the falloff), sr."""
    return 2.0 * math.pi * ((1.0 - cos_in) + 0.5 * (cos_in - cos_out))


@dataclass(frozen=True)
class Spec:
    """position (3,) m; unit axis (3,); cos_out = cos θo, cos_in = cos θi; intensity_cd (cd), flux_lm (lm)."""

    position: np.ndarray
    axis: np.ndarray
    cos_out: float
    cos_in: float
    intensity_cd: float
    flux_lm: float

    @classmethod
    def from_body(cls, body: dict, where: str) -> Spec:
        check_fields(body, where, NAME, FIELDS)
        position = vector_field(body, "position", where)
        axis = vector_field(body, "direction", where, unit=True)
        cone = field_value(body, FIELDS["cone_deg"], where)
        fall = field_value(body, FIELDS["falloff_deg"], where, default=0.0)
        problem = falloff_problem(cone, fall)
        if problem:
            raise LightError(f"{where}: {problem}")
        cos_out, cos_in = math.cos(math.radians(cone)), math.cos(math.radians(cone - fall))
        i0, flux = intensity_and_flux(body, where, spot_solid_angle(cos_out, cos_in))
        return cls(position, axis, cos_out, cos_in, i0, flux)


def falloff_problem(cone_deg: float, falloff_deg: float) -> str | None:
    """What is wrong with a spot's falloff against its cone (both degrees), or None: the one statement of the rule
    (`Spec.from_body` asks it, for the tracer and for the service's wire model alike)."""
    if falloff_deg > cone_deg:
        return f"'falloff_deg' ({falloff_deg:g}) must not exceed 'cone_deg' ({cone_deg:g})"
    return None


def pack(spec: Spec, j: int, out: Packing, where: str) -> float:
    """Fill row j; returns Φ (lm)."""
    row = out.par[j]
    a = spec.axis
    row[P_POS:P_POS + 3] = spec.position
    row[P_AXIS:P_AXIS + 3] = a
    row[P_COS_OUT], row[P_COS_IN] = spec.cos_out, spec.cos_in
    row[P_SOLID] = spot_solid_angle(spec.cos_out, spec.cos_in)
    row[P_I0], row[P_FLUX] = spec.intensity_cd, spec.flux_lm
    row[P_T:P_T + 3], row[P_B:P_B + 3] = onb(a[0], a[1], a[2])
    return spec.flux_lm


@njit(cache=True, _nrt=False)
def profile(L, j, dx, dy, dz):
    """Relative intensity I/I0 in [0, 1] of spot light j toward unit direction d."""
    p = L.par[j]
    c = dx * p[P_AXIS] + dy * p[P_AXIS + 1] + dz * p[P_AXIS + 2]
    co, ci = p[P_COS_OUT], p[P_COS_IN]
    if c >= ci:
        return 1.0
    if c <= co:
        return 0.0
    x = (c - co) / (ci - co)
    return x * x * (3.0 - 2.0 * x)


@njit(cache=True, _nrt=False)
def sample(L, j, u0, u1, u2, u3, u4):
    """A direction uniform in the cone θ ≤ θo; f = I/I0 × 2π(1 − cos θo) / P_SOLID (see base)."""
    p = L.par[j]
    co = p[P_COS_OUT]
    c = 1.0 - u0 * (1.0 - co)
    s = math.sqrt(max(0.0, 1.0 - c * c))
    phi = 2.0 * math.pi * u1
    x, y = s * math.cos(phi), s * math.sin(phi)
    dx, dy, dz = in_light_frame(p, x, y, c)
    inv = 1.0 / math.sqrt(dx * dx + dy * dy + dz * dz)
    dx, dy, dz = dx * inv, dy * inv, dz * inv
    f = profile(L, j, dx, dy, dz) * 2.0 * math.pi * (1.0 - co) / p[P_SOLID]
    return p[0], p[1], p[2], dx, dy, dz, f, False, 0.0, 0.0, 0.0


@njit(cache=True, _nrt=False)
def connect(L, j, x, y, z, nx, ny, nz, u1, u2, u3):
    """E = I(θ) cosθx / d² at x (lx), 0 outside the cone; a shadow ray to the position (see base)."""
    p = L.par[j]
    dx, dy, dz, d2, dist, cos_x = toward_point(p, x, y, z, nx, ny, nz)
    if cos_x <= 0.0:
        return 0.0, dx, dy, dz, 1.0
    inten = p[P_I0] * profile(L, j, -dx / dist, -dy / dist, -dz / dist)
    if inten <= 0.0:
        return 0.0, dx, dy, dz, 1.0
    return inten * cos_x / d2, dx, dy, dz, 1.0
