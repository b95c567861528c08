"""The rough surface of a `dielectric` (α > 0): a height field of Fresnel interfaces, GGX microfacets.

The row's columns are the `dielectric`'s (the index in column 0, so a solid nested in this one reads it as it reads a
smooth one's; roughness αx, αy and the brushing axis where `microfacet` keeps them); the inside is the dielectric's
medium. The surface is a height field of smooth Fresnel facets whose normals m follow the anisotropic GGX
distribution D(m) (as `microfacet`, whose D, Λ and visible-normal sampler it calls): Walter, Marschner, Li and
Torrance, "Microfacet models for refraction through rough surfaces", EGSR 2007. A photon arriving along d (indices
n1 where it is, n2 beyond, chosen with the medium stack exactly as the smooth surface does) picks a facet from the
normals it can see,
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
the smooth surface.

In a polarized scene the facet acts with the Fresnel Mueller matrices of reflection and transmission in its own
plane of incidence (s and p, total internal reflection and a coating included, `tracer.optics.thinfilm`): the photon
reflects with the probability its own state gives and leaves polarized, as on a smooth `dielectric`. It counts as
two polarizing interactions of diattenuation up to 1 (`tracer.effects`), as the smooth surface does.
"""

from __future__ import annotations

import math

from tracer.jit import njit
from tracer.optics.coating import coated_reflectance
from tracer.optics.polarization import ON, enter_plane, interface_power, leave_plane
from tracer.optics.spectra import WHITE_NM
from tracer.optics.surfaces.base import (
    ABSORBED,
    CONTINUES,
    STACK_FULL,
    arrival_normal,
    param,
    specular_normal,
)
from tracer.optics.surfaces.fresnel import fresnel_dielectric, refract
from tracer.optics.surfaces.microfacet import facet_frame, ggx_lambda, sample_visible_normal
from tracer.optics.thinfilm import stack_mueller
from tracer.rng import uniform


@njit(cache=True, error_model="numpy", _nrt=False)
def scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim, lam, pol):
    """What one facet of the rough surface does (the kinds' `scatter` contract, `base`), called by
    `dielectric.scatter` where the row's α > 0."""
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
