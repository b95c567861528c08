"""Collimated light: a parallel beam of illuminance E across it, from a disk or rectangle aperture.

Φ = E × aperture area. The aperture is centred on `origin`, across `direction`. A rectangle's height
runs along `up` (made perpendicular to `direction`), its width along up × direction; without `up`
its axes are any frame about `direction`. Not connectable: no shadow ray from a surface point can be
aimed at a beam of parallel rays, so only forward transport sees it.

==============  ============  =====  ============================================
Field           Type          Unit   Default
==============  ============  =====  ============================================
origin          3 floats      m      required (aperture centre)
direction       3 floats ≠ 0  —      required (the beam's direction; normalised)
illuminance_lx  float ≥ 0     lx     required
radius          float > 0     m      disk aperture: required, excludes width/height
width, height   float > 0     m      rectangle aperture: required without radius
up              3 floats      —      a frame about direction (rectangle only)
==============  ============  =====  ============================================

Parameter row: P_POS origin, P_AXIS direction, P_T, P_B the aperture's axes, P_I0 E (lx), P_SHAPE
`DISK` or `RECTANGLE`, P_R radius or half width, P_H half height (m), P_FLUX flux (lm).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tracer.jit import njit
from tracer.optics.fields import BodyField, fields
from tracer.optics.frames import onb
from tracer.optics.lights.base import (
    DELTA_DIRECTION,
    MAX_FLUX_LM,
    P_AXIS,
    P_B,
    P_FLUX,
    P_H,
    P_I0,
    P_POS,
    P_R,
    P_SHAPE,
    P_T,
    LightError,
    Packing,
    check_fields,
    field_value,
    vector_field,
)

NAME = "collimated"
FIELDS = fields(
    BodyField("origin", "point", "Centre of the aperture [x, y, z], m."),
    BodyField("direction", "direction", "Direction of travel (any length, not zero; dimensionless)."),
    BodyField("radius", "number", "Radius of a disk aperture, m.", required=False, lo=0.0, lo_open=True),
    BodyField("width", "number", "Width of a rectangular aperture, m.", required=False, lo=0.0, lo_open=True),
    BodyField("height", "number", "Height of a rectangular aperture (along `up`), m.", required=False, lo=0.0,
              lo_open=True),
    BodyField("up", "direction", "Orients a rectangle's height (dimensionless; not along direction).",
              required=False),
    BodyField("illuminance_lx", "number", "Illuminance on a plane across the beam, lx (unbounded: a pencil beam may be "
              "very bright; its flux, illuminance times aperture, is bounded).", lo=0.0))
EXAMPLE = {"type": "collimated", "name": "sun", "origin": [0.0, 0.0, 3.0], "direction": [0.3, 0.2, -1.0], "width": 4.0,
           "height": 4.0, "up": [0.0, 1.0, 0.0], "illuminance_lx": 100000.0,
           "spectrum": {"type": "blackbody", "kelvin": 5778.0}}
EFFECTS = ()
FLAGS = DELTA_DIRECTION
WHY_NOT_CONNECTABLE = "a collimated beam cannot be reached by shadow rays"
DISK, RECTANGLE = 0, 1  # the aperture's shape, in the P_SHAPE column


@dataclass(frozen=True)
class Spec:
    """origin (3,) m; unit direction (3,); the aperture's unit axes t, b (3,); illuminance_lx (lx);
    shape DISK (radius, m) or RECTANGLE (width along t, height along b, m; radius 0)."""

    origin: np.ndarray
    direction: np.ndarray
    t: np.ndarray
    b: np.ndarray
    illuminance_lx: float
    shape: int
    radius: float
    width: float
    height: float

    @classmethod
    def from_body(cls, body: dict, where: str) -> Spec:
        check_fields(body, where, NAME, FIELDS)
        origin = vector_field(body, "origin", where)
        a = vector_field(body, "direction", where, unit=True)
        e = field_value(body, FIELDS["illuminance_lx"], where)
        tt, bb = (np.array(v) for v in onb(a[0], a[1], a[2]))
        rect = "width" in body or "height" in body
        if ("radius" in body) == rect or (rect and not ("width" in body and "height" in body)):
            raise LightError(f"{where}: give either 'radius' (a disk aperture) or 'width' and 'height' (a rectangle)")
        if "radius" in body:
            if "up" in body:
                raise LightError(f"{where}: 'up' orients a rectangular aperture; a disk has none")
            r = field_value(body, FIELDS["radius"], where)
            return _bounded(cls(origin, a, tt, bb, e, DISK, r, 0.0, 0.0), math.pi * r * r, where)
        w = field_value(body, FIELDS["width"], where)
        h = field_value(body, FIELDS["height"], where)
        if "up" in body:
            up = vector_field(body, "up", where, unit=True)
            bb = up - a * float(up @ a)
            if np.linalg.norm(bb) < 1e-9:
                raise LightError(f"{where}: 'up' must not be parallel to 'direction'")
            bb = bb / np.linalg.norm(bb)
            tt = np.cross(bb, a)
        return _bounded(cls(origin, a, tt, bb, e, RECTANGLE, 0.0, w, h), w * h, where)


def _bounded(spec: Spec, area: float, where: str) -> Spec:
    """The spec, where its flux (illuminance × aperture area, lm) is within `MAX_FLUX_LM`: the illuminance itself is
    unbounded (a pencil beam may be very bright), a beam's whole flux is not."""
    if not spec.illuminance_lx * area <= MAX_FLUX_LM:
        raise LightError(f"{where}: its luminous flux {spec.illuminance_lx * area:.3g} lm (illuminance_lx × aperture) "
                         f"is beyond {MAX_FLUX_LM:g} lm (or not finite): check the magnitude and unit of "
                         f"'illuminance_lx' and of the aperture")
    return spec


def pack(spec: Spec, j: int, out: Packing, where: str) -> float:
    """Fill row j; returns Φ = E × aperture area (lm)."""
    row = out.par[j]
    e = spec.illuminance_lx
    row[P_POS:P_POS + 3] = spec.origin
    row[P_AXIS:P_AXIS + 3] = spec.direction
    row[P_T:P_T + 3], row[P_B:P_B + 3] = spec.t, spec.b
    row[P_I0] = e
    row[P_SHAPE] = spec.shape
    if spec.shape == DISK:
        r = spec.radius
        row[P_R] = r
        row[P_FLUX] = e * math.pi * r * r
    else:
        row[P_R], row[P_H] = 0.5 * spec.width, 0.5 * spec.height
        row[P_FLUX] = e * spec.width * spec.height
    return row[P_FLUX]


@njit(cache=True, _nrt=False)
def sample(L, j, u0, u1, u2, u3, u4):
    """A uniform point of the aperture, the beam's direction; f = 1 (see base)."""
    p = L.par[j]
    if p[P_SHAPE] == DISK:
        r = p[P_R] * math.sqrt(u0)
        phi = 2.0 * math.pi * u1
        a, b = r * math.cos(phi), r * math.sin(phi)
    else:
        a, b = (2.0 * u0 - 1.0) * p[P_R], (2.0 * u1 - 1.0) * p[P_H]
    ox = p[0] + a * p[P_T] + b * p[P_B]
    oy = p[1] + a * p[P_T + 1] + b * p[P_B + 1]
    oz = p[2] + a * p[P_T + 2] + b * p[P_B + 2]
    return ox, oy, oz, p[P_AXIS], p[P_AXIS + 1], p[P_AXIS + 2], 1.0, False, 0.0, 0.0, 0.0


@njit(cache=True, _nrt=False)
def connect(L, j, x, y, z, nx, ny, nz, u1, u2, u3):
    """Nothing: a parallel beam cannot be reached by a shadow ray (its FLAGS hold DELTA_DIRECTION)."""
    return 0.0, 0.0, 0.0, 0.0, 0.0
