"""Goniometric light: a point with the type-C intensity table of an IES or EULUMDAT file.

The table is `tracer.photometry.files`'s (bilinear in C and γ). The luminaire's γ = 0 axis is `direction`
and its C = 0 half-plane contains `c0` (only the part of c0 across direction counts); C = 90° lies
along c0 × direction (+y by default). An attached light turns with its node because the service turns
both axes. Photons leave in a table cell chosen in proportion to its flux, uniformly in solid angle
within it, so f = I(ω) ΔΩ / (P(cell) Φ) stays close to 1.

==========  ============  =====  ===============================================
Field       Type          Unit   Default
==========  ============  =====  ===============================================
position    3 floats      m      required
format      str           —      required: "ies" or "ldt"
data        str           —      required: the file's text
direction   3 floats ≠ 0  —      [0, 0, −1] (γ = 0, the nadir; normalised)
c0          3 floats ≠ 0  —      [1, 0, 0] (in the C = 0 half-plane; not ∥ direction)
==========  ============  =====  ===============================================

Parameter row: P_POS position, P_AXIS the γ = 0 axis, P_T the C = 0 axis, P_B the C = 90° axis,
P_FLUX the table's flux (lm), P_I0 its largest intensity (cd). Tables: g_c, g_gamma (rad), g_cd (cd,
nc × ng row-major), g_cell_cdf (cells ∝ flux), found through g_off and g_n (see `LightArrays`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tracer.jit import njit
from tracer.optics.fields import BodyField, fields
from tracer.optics.frames import find_in_cdf
from tracer.optics.lights.base import (
    DELTA_POSITION,
    P_AXIS,
    P_B,
    P_FLUX,
    P_I0,
    P_POS,
    P_T,
    LightError,
    Packing,
    check_fields,
    in_light_frame,
    toward_point,
    vector_field,
)
from tracer.photometry.files import Photometry, parse_photometry

NAME = "goniometric"
FIELDS = fields(
    BodyField("position", "point", "The photometric centre [x, y, z], m."),
    BodyField("format", "choice", "`ies` (IES LM-63) or `ldt` (EULUMDAT).", choices=("ies", "ldt")),
    BodyField("data", "text", "The file's text (intensities in cd, or cd/klm scaled by its lumens).",
              max_length=10_000_000),
    BodyField("direction", "direction", "The γ = 0 axis (dimensionless); default −z, straight down.", required=False),
    BodyField("c0", "direction", "The C = 0 half-plane's direction (dimensionless); default +x.", required=False))
#: a small type-C downlight (IES LM-63-2002): 1000 lm, intensities in cd per 1000 lm, rotationally symmetric
IES_EXAMPLE = ("IESNA:LM-63-2002\n[TEST]LumenLink example\n[MANUFAC]LumenLink\n[LUMINAIRE]recessed downlight\n"
               "TILT=NONE\n1 1000 1 5 1 1 2 0.2 0.2 0\n1.0 1.0 12\n0 22.5 45 67.5 90\n0\n400 350 220 60 0\n")
EXAMPLE = {"type": "goniometric", "name": "downlight", "position": [0.0, 0.0, 2.8], "format": "ies",
           "data": IES_EXAMPLE}
EFFECTS = ()
FLAGS = DELTA_POSITION


def _frame(body: dict, where: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The luminaire's γ = 0 axis, C = 0 axis and C = 90° axis (an orthonormal frame) from its body."""
    nadir = vector_field(body, "direction", where, unit=True) if "direction" in body else np.array([0.0, 0.0, -1.0])
    c0 = vector_field(body, "c0", where, unit=True) if "c0" in body else np.array([1.0, 0.0, 0.0])
    x = c0 - nadir * float(c0 @ nadir)
    if np.linalg.norm(x) < 1e-9:
        if "c0" in body:
            raise LightError(f"{where}: 'c0' must not be parallel to 'direction'")
        x = np.array([0.0, 1.0, 0.0]) - nadir * nadir[1]  # the default +x is the axis itself: take +y
    x = x / np.linalg.norm(x)
    return nadir, x, np.cross(x, nadir)


@dataclass(frozen=True)
class Spec:
    """position (3,) m; the unit axes gamma0 (γ = 0), c0 (C = 0), c90 (C = 90°) (3,); the parsed table."""

    position: np.ndarray
    gamma0: np.ndarray
    c0: np.ndarray
    c90: np.ndarray
    photometry: Photometry

    @classmethod
    def from_body(cls, body: dict, where: str) -> Spec:
        check_fields(body, where, NAME, FIELDS)
        position = vector_field(body, "position", where)
        gamma0, c0, c90 = _frame(body, where)
        fmt = body.get("format")
        data = body.get("data")
        if fmt not in FIELDS["format"].choices:
            raise LightError(f"{where}: 'format' must be 'ies' or 'ldt', got {fmt!r}")
        if not isinstance(data, str):
            raise LightError(f"{where}: 'data' must be the file text")
        try:
            ph = parse_photometry(fmt, data)
        except ValueError as exc:
            raise LightError(f"{where}: invalid {fmt} photometry file: {exc}") from None
        return cls(position, gamma0, c0, c90, ph)


def pack(spec: Spec, j: int, out: Packing, where: str) -> float:
    """Fill row j and append the light's table; returns the table's flux (lm)."""
    row = out.par[j]
    ph = spec.photometry
    row[P_POS:P_POS + 3] = spec.position
    row[P_AXIS:P_AXIS + 3], row[P_T:P_T + 3], row[P_B:P_B + 3] = spec.gamma0, spec.c0, spec.c90
    cells = ph.cell_flux()
    flux = float(cells.sum())
    row[P_FLUX] = flux
    row[P_I0] = ph.max_candela()
    out.g_off[j] = [out.used(name) for name in ("g_c", "g_gamma", "g_cd", "g_cell_cdf")]
    out.g_n[j] = len(ph.c_deg), len(ph.gamma_deg)
    cdf = np.cumsum(cells.ravel())
    out.parts["g_c"].append(np.radians(ph.c_deg))
    out.parts["g_gamma"].append(np.radians(ph.gamma_deg))
    out.parts["g_cd"].append(ph.candela.ravel())
    out.parts["g_cell_cdf"].append(cdf / cdf[-1])
    return flux


@njit(cache=True, _nrt=False)
def _interval(grid, lo, n, x):
    """Index k in [0, n-2] with grid[lo+k] <= x <= grid[lo+k+1] (clamped)."""
    a, b = 0, n - 2
    while a < b:
        mid = (a + b + 1) // 2
        if grid[lo + mid] <= x:
            a = mid
        else:
            b = mid - 1
    return a


@njit(cache=True, _nrt=False)
def intensity(L, j, dx, dy, dz):
    """Intensity in cd of goniometric light j toward unit direction d (bilinear in C, γ)."""
    c0, g0, t0 = L.g_off[j, 0], L.g_off[j, 1], L.g_off[j, 2]
    nc, ng = L.g_n[j, 0], L.g_n[j, 1]
    p = L.par[j]
    cos_gam = dx * p[P_AXIS] + dy * p[P_AXIS + 1] + dz * p[P_AXIS + 2]
    gam = math.acos(min(1.0, max(-1.0, cos_gam)))
    c = math.atan2(dx * p[P_B] + dy * p[P_B + 1] + dz * p[P_B + 2], dx * p[P_T] + dy * p[P_T + 1] + dz * p[P_T + 2])
    if c < 0.0:
        c += 2.0 * math.pi
    ic = _interval(L.g_c, c0, nc, c)
    ig = _interval(L.g_gamma, g0, ng, gam)
    ca, cb = L.g_c[c0 + ic], L.g_c[c0 + ic + 1]
    ga, gb = L.g_gamma[g0 + ig], L.g_gamma[g0 + ig + 1]
    tc = (c - ca) / (cb - ca) if cb > ca else 0.0
    tg = (gam - ga) / (gb - ga) if gb > ga else 0.0
    tc = min(1.0, max(0.0, tc))
    tg = min(1.0, max(0.0, tg))
    base = t0 + ic * ng + ig
    i00 = L.g_cd[base]
    i01 = L.g_cd[base + 1]
    i10 = L.g_cd[base + ng]
    i11 = L.g_cd[base + ng + 1]
    return (1 - tc) * (1 - tg) * i00 + (1 - tc) * tg * i01 + tc * (1 - tg) * i10 + tc * tg * i11


@njit(cache=True, _nrt=False)
def sample(L, j, u0, u1, u2, u3, u4):
    """A cell in proportion to its flux (u0), then uniform in solid angle within it (u1, u2) (see base)."""
    p = L.par[j]
    c0, g0, e0 = L.g_off[j, 0], L.g_off[j, 1], L.g_off[j, 3]
    nc, ng = L.g_n[j, 0], L.g_n[j, 1]
    ncell = (nc - 1) * (ng - 1)
    cell = find_in_cdf(L.g_cell_cdf, e0, ncell, u0)
    pc = L.g_cell_cdf[e0 + cell] - (L.g_cell_cdf[e0 + cell - 1] if cell > 0 else 0.0)
    ic = cell // (ng - 1)
    ig = cell - ic * (ng - 1)
    ca, cb = L.g_c[c0 + ic], L.g_c[c0 + ic + 1]
    ga, gb = L.g_gamma[g0 + ig], L.g_gamma[g0 + ig + 1]
    c = ca + u1 * (cb - ca)
    cga, cgb = math.cos(ga), math.cos(gb)
    cg = cga + u2 * (cgb - cga)
    sg = math.sqrt(max(0.0, 1.0 - cg * cg))
    a, b = sg * math.cos(c), sg * math.sin(c)  # along the C = 0 and C = 90° axes; cg along γ = 0
    dx, dy, dz = in_light_frame(p, a, b, cg)
    d_omega = (cb - ca) * (cga - cgb)
    f = intensity(L, j, dx, dy, dz) * d_omega / (pc * p[P_FLUX]) if pc > 0.0 else 0.0
    return p[0], p[1], p[2], dx, dy, dz, f, False, 0.0, 0.0, 0.0


@njit(cache=True, _nrt=False)
def connect(L, j, x, y, z, nx, ny, nz, u1, u2, u3):
    """E = I(C, γ) cosθx / d² at x (lx) from the table; a shadow ray to the position (see base)."""
    p = L.par[j]
    dx, dy, dz, d2, dist, cos_x = toward_point(p, x, y, z, nx, ny, nz)
    if cos_x <= 0.0:
        return 0.0, dx, dy, dz, 1.0
    inten = intensity(L, j, -dx / dist, -dy / dist, -dz / dist)
    if inten <= 0.0:
        return 0.0, dx, dy, dz, 1.0
    return inten * cos_x / d2, dx, dy, dz, 1.0
