"""``rough_dielectric``: a solid of refractive index n whose surface is rough or brushed, GGX microfacets.

| field | type | unit | range | default |
| --- | --- | --- | --- | --- |
| ior | float, Sellmeier or table (`tracer.optics.spectra`) | — | (0, 10] | required |
| alpha | float: GGX roughness α (along `axis` where brushed) | — | [1e-4, 1] | required |
| alpha_y | float: α across `axis` (anisotropic, brushed) | — | [1e-4, 1] | `alpha` (isotropic) |
| axis | [x, y, z]: the direction of `alpha` in the node's frame (brushing) | — | not zero | a frame of the normal |
| absorption_per_m | float or table over λ | 1/m | [0, 1e9] | 0 |
| scattering_per_m | float | 1/m | [0, 1e9] | 0 |
| g | float | — | (−1, 1) | 0 |
| coating | thin films on every facet (`tracer.optics.coating`) | — | — | none |
| fluorescence | inside (`tracer.optics.media.fluorescence`) | — | — | none |
| particles | spheres inside (`tracer.optics.mie`) | — | — | none |

Everything but the surface is `dielectric`'s, with the same fields and meaning (the index in the row's column 0, so
a solid nested in this one reads it as it reads a smooth one's; the inside the same medium). The surface is a height
field of smooth Fresnel facets whose normals m follow the anisotropic GGX distribution D(m) (as `microfacet`,
whose D, Λ and visible-normal sampler this kind calls): Walter, Marschner, Li and Torrance, "Microfacet models for
refraction through rough surfaces", EGSR 2007. A photon arriving along d (indices n1 where it is, n2 beyond, chosen
with the medium stack exactly as `dielectric` does) picks a facet from the normals it can see,
D_wi(m) = G1(wi) max(0, wi·m) D(m) / (wi·n) (Heitz, "Sampling the GGX distribution of visible normals", JCGT 7(4)
2018), then reflects about m with the facet's Fresnel reflectance F(wi·m) (a coated facet's: its transfer-matrix
reflectance at that angle) and otherwise refracts through it by Snell's law (n1 = n2: straight on); it survives
with probability G2/G1 = (1 + Λ(wi)) / (1 + Λ(wi) + Λ(wo)) (Smith's height-correlated masking-shadowing, the
form pbrt-v4 uses for both reflection and transmission; Λ depends only on wo's slope, taken on its own side). A
reflected direction below the surface or a refracted one above it is absorbed. The density of the surviving
outgoing directions is then Walter's BSDF times |cos θo| exactly (eqs. 20 and 21: reflection F D G2 / (4 |cos θi|)
and transmission |wi·m| |wo·m| n2² (1 − F) D G2 / (|cos θi| (n1 wi·m + n2 wo·m)²), m the half vector of each), a
flux (photon) BSDF: no (n1/n2)² radiance factor.

Single scattering: what a second bounce between facets would send on is lost, as with `microfacet`; for n = 1.5
from air at normal incidence R + T = 0.99506 (α = 0.2), 0.96811 (α = 0.5) and 0.89334 (α = 1)
(tests/tracer/optics/test_rough_dielectric.py integrates Walter's BSDF independently). As α → 0 it becomes
`dielectric`.

In a polarized scene the facet acts with the Fresnel Mueller matrices of reflection and transmission in its own
plane of incidence (s and p, total internal reflection and a coating included, `tracer.optics.thinfilm`): the photon
reflects with the probability its own state gives and leaves polarized, as on a smooth `dielectric`. It counts as
two polarizing interactions of diattenuation up to 1 (`tracer.effects`), as `dielectric` does.

Effects: as `dielectric` (`fresnel`, + `absorption`, `scattering`, `dispersion`, `coating`, `fluorescence`, `mie`,
`spectral`). Backward estimator: no.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tracer.jit import njit
from tracer.optics.coating import Coating, coated_reflectance, parse_coating
from tracer.optics.elements.base import parse_axis
from tracer.optics.media.fluorescence import Fluorescence, parse_fluorescence
from tracer.optics.mie import Particles, parse_particles
from tracer.optics.polarization import ON, enter_plane, interface_power, leave_plane
from tracer.optics.spectra import WHITE_NM, scalar
from tracer.optics.surfaces import dielectric
from tracer.optics.surfaces.base import (
    ABSORBED,
    CONTINUES,
    GLOSSY,
    STACK_FULL,
    TRANSMITS,
    arrival_normal,
    bounds,
    optional,
    param,
    specular_normal,
)
from tracer.optics.surfaces.dielectric import fresnel_dielectric, refract
from tracer.optics.surfaces.microfacet import ALPHA_MIN, facet_frame, ggx_lambda, sample_visible_normal
from tracer.optics.thinfilm import stack_mueller
from tracer.rng import uniform

NAME = "rough_dielectric"
FLAGS = GLOSSY | TRANSMITS


@dataclass(frozen=True)
class Spec:
    """`dielectric`'s fields and a GGX roughness (and across a brushing axis)."""

    ior: Any = field(metadata=bounds(0.0, 10.0, lo_open=True, value="ior", column=0,
                                     doc="refractive index n (dimensionless): a number, {sellmeier: {b, c_um2}} or "
                                         "{table: {nm, n}}"))
    alpha: float = field(metadata=bounds(ALPHA_MIN, 1.0, doc="GGX roughness α (along `axis` where brushed)"))
    alpha_y: float | None = field(default=None, metadata=bounds(ALPHA_MIN, 1.0, doc="GGX roughness across `axis`"))
    axis: tuple[float, float, float] | None = field(default=None, metadata=optional(
        parse_axis, "the direction of `alpha` [x, y, z] in the node's frame (brushing)"))
    absorption_per_m: Any = field(default=0.0, metadata=bounds(0.0, 1e9, value="spectral", mcolumn=0,
                                                               doc="absorption coefficient σa, 1/m (or a table)"))
    scattering_per_m: float = field(default=0.0, metadata=bounds(0.0, 1e9, doc="scattering coefficient σs, 1/m"))
    g: float = field(default=0.0, metadata=bounds(-1.0, 1.0, lo_open=True, hi_open=True,
                                                  doc="Henyey–Greenstein asymmetry g, dimensionless "
                                                      "(−1 backward, 0 isotropic, 1 forward)"))
    coating: Coating | None = field(default=None, metadata=optional(
        parse_coating, "thin films on every facet, outermost first"))
    fluorescence: Fluorescence | None = field(default=None, metadata=optional(
        parse_fluorescence, "absorption and isotropic re-emission inside"))
    particles: Particles | None = field(default=None, metadata=optional(
        parse_particles, "spheres suspended inside: Mie scattering and absorption at each wavelength"))

    # the inside is a dielectric's: its rules and Mie table read the same fields
    check = dielectric.Spec.check
    mie = dielectric.Spec.mie


def row(spec: Spec) -> np.ndarray:
    """[n, 0, 0, 0, αx, αy, axis (3), axis?]: the index in column 0 as `dielectric`, roughness where `microfacet`
    keeps it."""
    ay = spec.alpha if spec.alpha_y is None else spec.alpha_y
    ax = (0.0, 0.0, 0.0, 0.0) if spec.axis is None else (*spec.axis, 1.0)
    return np.array([scalar(spec.ior), 0.0, 0.0, 0.0, spec.alpha, ay, *ax])


# the inside, the effects and the polarizing interactions are the smooth dielectric's (they read the same fields)
medium = dielectric.medium
medium_tables = dielectric.medium_tables
medium_phase = dielectric.medium_phase
polarizing = dielectric.polarizing
effects = dielectric.effects


def diffuse_only(spec: Spec) -> bool:
    return False


@njit(cache=True, error_model="numpy", _nrt=False)
def scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim, lam, pol):
    fx, fy, fz = arrival_normal(ngx, ngy, ngz, dx, dy, dz)
    entering = dx * ngx + dy * ngy + dz * ngz < 0.0
    pos = -1
    if entering:   # the indices on either side, from the medium stack, as `dielectric.scatter`
        n1 = param(M, med[depth - 1], 0, lam) if depth > 0 else 1.0
        n2 = param(M, inst, 0, lam)
    else:
        n1 = param(M, inst, 0, lam)
        for k in range(depth - 1, -1, -1):
            if med[k] == inst:
                pos = k
                break
        if pos >= 0:
            n2 = param(M, med[pos - 1], 0, lam) if pos > 0 else 1.0
        elif depth > 0 and med[depth - 1] != inst:
            n2 = param(M, med[depth - 1], 0, lam)
        else:
            n2 = 1.0
    nx, ny, nz = specular_normal(sa, inst, prim, hu, hv, fx, fy, fz)
    ax, ay = M.par[inst, 4], M.par[inst, 5]
    tx, ty, tz, bx, by, bz = facet_frame(sa, M, inst, nx, ny, nz)
    wx, wy, wz = -(dx * tx + dy * ty + dz * tz), -(dx * bx + dy * by + dz * bz), -(dx * nx + dy * ny + dz * nz)
    if wz <= 0.0:   # grazing the shading normal from below: no facet is visible
        return ABSORBED, dx, dy, dz, 0.0, depth, dim + 4
    mx, my, mz = sample_visible_normal(wx, wy, wz, ax, ay, uniform(key, dim + 1), uniform(key, dim + 2))
    cos_m = min(max(wx * mx + wy * my + wz * mz, 0.0), 1.0)
    wmx, wmy, wmz = mx * tx + my * bx + mz * nx, mx * ty + my * by + mz * ny, mx * tz + my * bz + mz * nz
    polarized = pol[ON] != 0.0
    sx, sy, sz, rs2, rp2, cr, dr, ts2, tp2, ct, dt = wmx, wmy, wmz, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0
    if polarized:   # the facet's Mueller matrices, in its own plane of incidence, for this photon's state
        sx, sy, sz = enter_plane(pol, dx, dy, dz, wmx, wmy, wmz)
        rs2, rp2, cr, dr, ts2, tp2, ct, dt = stack_mueller(
            M.layers, M.coat[inst, 0], M.coat[inst, 1] if lam > 0.0 else 0, not entering, n1, n2, 0.0,
            lam if lam > 0.0 else WHITE_NM, cos_m)
        pr, pt = interface_power(pol, rs2, rp2), interface_power(pol, ts2, tp2)
        r = pr / (pr + pt) if pr + pt > 0.0 else 1.0
    elif M.coat[inst, 1] > 0 and lam > 0.0:
        r = coated_reflectance(M, inst, entering, n1, n2, 0.0, lam, cos_m)
    else:
        r = fresnel_dielectric(cos_m, n1, n2)
    transmitted = False
    if uniform(key, dim) < r:
        ox, oy, oz = 2.0 * cos_m * mx - wx, 2.0 * cos_m * my - wy, 2.0 * cos_m * mz - wz
    elif n1 == n2:   # index-matched: straight on
        ox, oy, oz = -wx, -wy, -wz
        transmitted = True
    else:
        ok, ox, oy, oz = refract(-wx, -wy, -wz, mx, my, mz, n1 / n2)
        if ok:
            transmitted = True
        else:   # rounding at the critical angle: total internal reflection
            ox, oy, oz = 2.0 * cos_m * mx - wx, 2.0 * cos_m * my - wy, 2.0 * cos_m * mz - wz
    if (oz <= 0.0) != transmitted:   # onto the wrong side: another facet would take it (single scattering)
        return ABSORBED, dx, dy, dz, 0.0, depth, dim + 4
    li = ggx_lambda(wx, wy, wz, ax, ay)
    g = (1.0 + li) / (1.0 + li + ggx_lambda(ox, oy, abs(oz), ax, ay))
    if uniform(key, dim + 3) >= g:   # masked or shadowed by another facet
        return ABSORBED, dx, dy, dz, 0.0, depth, dim + 4
    rx, ry, rz = ox * tx + oy * bx + oz * nx, ox * ty + oy * by + oz * ny, ox * tz + oy * bz + oz * nz
    inv = 1.0 / math.sqrt(rx * rx + ry * ry + rz * rz)
    rx, ry, rz = rx * inv, ry * inv, rz * inv
    if (rx * fx + ry * fy + rz * fz <= 0.0) != transmitted:   # a shading normal far from the geometric one
        return ABSORBED, dx, dy, dz, 0.0, depth, dim + 4
    if polarized:
        if transmitted:
            leave_plane(pol, ts2, tp2, ct, dt, rx, ry, rz, sx, sy, sz)
        else:
            leave_plane(pol, rs2, rp2, cr, dr, rx, ry, rz, sx, sy, sz)
    if transmitted:
        if entering:
            if depth == med.shape[0]:
                return STACK_FULL, rx, ry, rz, 0.0, depth, dim + 4
            med[depth] = inst
            depth += 1
        elif pos >= 0:
            for k in range(pos, depth - 1):
                med[k] = med[k + 1]
            depth -= 1
    return CONTINUES, rx, ry, rz, 1.0, depth, dim + 4
