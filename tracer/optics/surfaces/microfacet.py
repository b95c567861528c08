"""``microfacet``: a rough or brushed reflector, GGX (Trowbridge–Reitz) microfacets, on both sides.

| field | type | unit | range | default |
| --- | --- | --- | --- | --- |
| alpha | float: GGX roughness α (along `axis` where brushed) | — | [1e-4, 1] | required |
| alpha_y | float: α across `axis` (anisotropic, brushed) | — | [1e-4, 1] | `alpha` (isotropic) |
| axis | [x, y, z]: the direction of `alpha` in the node's frame (brushing) | — | not zero | a frame of the normal |
| reflectance | float or table over λ: a facet's reflectance at every angle | fraction | [0, 1] | one of the two |
| metal | [n, k]: the metal's complex index n − ik, Fresnel at each facet's angle | — | as `mirror` | one of the two |

The surface is a height field of mirror facets whose normals m follow the anisotropic GGX distribution
D(m) = 1 / (π αx αy cos⁴θm (1 + tan²θm (cos²φm/αx² + sin²φm/αy²))²) about the shading normal (Walter et al.,
EGSR 2007; Heitz, JCGT 2014). A photon arriving along d picks a facet from the distribution of the normals it can
see, D_wi(m) = G1(wi) max(0, wi·m) D(m) / (wi·n) (Heitz, "Sampling the GGX distribution of visible normals", JCGT
7(4) 2018, the method sampled here exactly), reflects about it, and survives with probability F(wi·m) G2/G1(wi):
F is `reflectance` or the metal's Fresnel reflectance at the facet's angle (under a polarized photon, the power its
own state gives through the metal's Mueller matrix in the facet's plane of incidence, and it leaves with that
matrix applied), G2/G1 = (1 + Λ(wi)) / (1 + Λ(wi) + Λ(wo)) is Smith's height-correlated masking-shadowing
(Λ(w) = (−1 + √(1 + α(w)² tan²θ)) / 2, α(w) the roughness along w's azimuth), and a direction below the surface
is absorbed. This is the single-scattering model: with F = 1 it loses the energy that real surfaces send on in a
second bounce between facets, 1 − E(μ): at normal incidence 5.2 % at α = 0.2, 31 % at α = 0.5 and 69 % at α = 1
(tests/tracer/optics/test_microfacet.py integrates E(μ) independently). As α → 0 it becomes `mirror`.

Effects: `specular` (+ `spectral` for a table). Backward estimator: no. Polarization (`tracer.effects`): a metal
facet diattenuates as the metal does; a constant `reflectance` does not.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tracer.jit import njit
from tracer.optics.elements.base import parse_axis, sheet_axis
from tracer.optics.frames import onb
from tracer.optics.polarization import ON, enter_plane, interface_power, leave_plane
from tracer.optics.spectra import WHITE_NM, scalar, varies
from tracer.optics.surfaces.base import (
    ABSORBED,
    CONTINUES,
    GLOSSY,
    arrival_normal,
    bounds,
    optional,
    param,
    specular_normal,
)
from tracer.optics.surfaces.mirror import metal_diattenuation, parse_metal
from tracer.optics.thinfilm import stack_mueller, stack_reflectance
from tracer.rng import uniform

NAME = "microfacet"
FLAGS = GLOSSY
ALPHA_MIN = 1e-4


@dataclass(frozen=True)
class Spec:
    """GGX roughness (and across a brushing axis), and a facet's reflectance or a metal's complex index."""

    alpha: float = field(metadata=bounds(ALPHA_MIN, 1.0, doc="GGX roughness α (along `axis` where brushed)"))
    alpha_y: float | None = field(default=None, metadata=bounds(ALPHA_MIN, 1.0, doc="GGX roughness across `axis`"))
    axis: tuple[float, float, float] | None = field(default=None, metadata=optional(
        parse_axis, "the direction of `alpha` [x, y, z] in the node's frame (brushing)"))
    reflectance: Any = field(default=None, metadata=bounds(0.0, 1.0, value="spectral", column=0,
                                                           doc="a facet's reflectance, fraction (or a table over λ)"))
    metal: tuple[float, float] | None = field(default=None, metadata=optional(
        parse_metal, "the metal's complex index [n, k] (n − ik), instead of a reflectance"))

    def check(self) -> str | None:
        if (self.reflectance is None) == (self.metal is None):
            return "give exactly one of 'reflectance' and 'metal'"
        return None


def row(spec: Spec) -> np.ndarray:
    """[R, n, k, metal?, αx, αy, axis (3), axis?]: 10 columns."""
    ay = spec.alpha if spec.alpha_y is None else spec.alpha_y
    r, n, k, metal = (scalar(spec.reflectance), 0.0, 0.0, 0.0) if spec.metal is None else (0.0, *spec.metal, 1.0)
    ax = (0.0, 0.0, 0.0, 0.0) if spec.axis is None else (*spec.axis, 1.0)
    return np.array([r, n, k, metal, spec.alpha, ay, *ax])


def effects(spec: Spec) -> tuple[str, ...]:
    return ("specular", "spectral") if varies(spec.reflectance) else ("specular",)


def diffuse_only(spec: Spec) -> bool:
    return False


def polarizing(spec: Spec) -> tuple[int, float]:
    """A metal's facets diattenuate as the metal does (its largest |Rs − Rp| / (Rs + Rp)); a constant reflectance
    acts alike on s and p (`tracer.effects`)."""
    return (0, 0.0) if spec.metal is None else (1, metal_diattenuation(*spec.metal))


# ----------------------------------------------------------------------------------------- GGX, written once


@njit(cache=True, error_model="numpy", _nrt=False)
def ggx_lambda(x, y, z, ax, ay):
    """Smith's Λ of the unit local direction (x, y, z) (z along the normal) for roughness (ax, ay)."""
    if z <= 0.0:
        return 1e300
    t2 = (ax * ax * x * x + ay * ay * y * y) / (z * z)
    return 0.5 * (-1.0 + math.sqrt(1.0 + t2))


@njit(cache=True, error_model="numpy", _nrt=False)
def ggx_d(x, y, z, ax, ay):
    """GGX normal distribution D(m) of the unit local microfacet normal m = (x, y, z)."""
    if z <= 0.0:
        return 0.0
    a = x * x / (ax * ax) + y * y / (ay * ay) + z * z
    return 1.0 / (math.pi * ax * ay * a * a)


@njit(cache=True, error_model="numpy", _nrt=False)
def sample_visible_normal(x, y, z, ax, ay, u1, u2):
    """A microfacet normal drawn from the normals visible from the unit local direction (x, y, z), z > 0
    (Heitz 2018, listing 1)."""
    vx, vy, vz = ax * x, ay * y, z
    inv = 1.0 / math.sqrt(vx * vx + vy * vy + vz * vz)
    vx, vy, vz = vx * inv, vy * inv, vz * inv
    l2 = vx * vx + vy * vy
    if l2 > 0.0:
        il = 1.0 / math.sqrt(l2)
        t1x, t1y, t1z = -vy * il, vx * il, 0.0
    else:
        t1x, t1y, t1z = 1.0, 0.0, 0.0
    t2x, t2y, t2z = vy * t1z - vz * t1y, vz * t1x - vx * t1z, vx * t1y - vy * t1x
    r = math.sqrt(u1)
    phi = 2.0 * math.pi * u2
    p1 = r * math.cos(phi)
    p2 = r * math.sin(phi)
    s = 0.5 * (1.0 + vz)
    p2 = (1.0 - s) * math.sqrt(max(0.0, 1.0 - p1 * p1)) + s * p2
    p3 = math.sqrt(max(0.0, 1.0 - p1 * p1 - p2 * p2))
    nx = p1 * t1x + p2 * t2x + p3 * vx
    ny = p1 * t1y + p2 * t2y + p3 * vy
    nz = p1 * t1z + p2 * t2z + p3 * vz
    mx, my, mz = ax * nx, ay * ny, max(1e-12, nz)
    inv = 1.0 / math.sqrt(mx * mx + my * my + mz * mz)
    return mx * inv, my * inv, mz * inv


@njit(cache=True, error_model="numpy", _nrt=False)
def facet_frame(sa, M, inst, nx, ny, nz):
    """The tangent t and bitangent b of the GGX frame (t, b, n) at shading normal n: t along the node's brushing axis
    (parameter columns 6–8, flag 9) taken onto the tangent plane where the surface is brushed, any tangent else.
    Shared by every GGX surface (`microfacet`, a rough `dielectric`), whose parameter rows keep these columns."""
    if M.par[inst, 9] > 0.0:   # brushed: alpha along the node's axis, taken onto the tangent plane
        tx, ty, tz = sheet_axis(sa, inst, M.par[inst, 6], M.par[inst, 7], M.par[inst, 8], nx, ny, nz)
        c = tx * nx + ty * ny + tz * nz
        tx, ty, tz = tx - c * nx, ty - c * ny, tz - c * nz
        ln = math.sqrt(tx * tx + ty * ty + tz * tz)
        if ln > 1e-9:
            tx, ty, tz = tx / ln, ty / ln, tz / ln
        else:
            (tx, ty, tz), _ = onb(nx, ny, nz)
    else:
        (tx, ty, tz), _ = onb(nx, ny, nz)
    return tx, ty, tz, ny * tz - nz * ty, nz * tx - nx * tz, nx * ty - ny * tx


@njit(cache=True, error_model="numpy", _nrt=False)
def scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim, lam, pol):
    fx, fy, fz = arrival_normal(ngx, ngy, ngz, dx, dy, dz)
    nx, ny, nz = specular_normal(sa, inst, prim, hu, hv, fx, fy, fz)
    ax, ay = M.par[inst, 4], M.par[inst, 5]
    tx, ty, tz, bx, by, bz = facet_frame(sa, M, inst, nx, ny, nz)
    # wi = −d in the frame (t, b, n)
    wx, wy, wz = -(dx * tx + dy * ty + dz * tz), -(dx * bx + dy * by + dz * bz), -(dx * nx + dy * ny + dz * nz)
    if wz <= 0.0:   # grazing the shading normal from below: no facet is visible
        return ABSORBED, dx, dy, dz, 0.0, depth, dim + 3
    mx, my, mz = sample_visible_normal(wx, wy, wz, ax, ay, uniform(key, dim), uniform(key, dim + 1))
    cos_m = wx * mx + wy * my + wz * mz
    ox, oy, oz = 2.0 * cos_m * mx - wx, 2.0 * cos_m * my - wy, 2.0 * cos_m * mz - wz
    if oz <= 0.0:   # into the surface: another facet would take it (the single-scattering loss)
        return ABSORBED, dx, dy, dz, 0.0, depth, dim + 3
    li = ggx_lambda(wx, wy, wz, ax, ay)
    g = (1.0 + li) / (1.0 + li + ggx_lambda(ox, oy, oz, ax, ay))
    # world directions of the facet normal and the outgoing photon
    wmx, wmy, wmz = mx * tx + my * bx + mz * nx, mx * ty + my * by + mz * ny, mx * tz + my * bz + mz * nz
    rx, ry, rz = ox * tx + oy * bx + oz * nx, ox * ty + oy * by + oz * ny, ox * tz + oy * bz + oz * nz
    inv = 1.0 / math.sqrt(rx * rx + ry * ry + rz * rz)
    rx, ry, rz = rx * inv, ry * inv, rz * inv
    if rx * fx + ry * fy + rz * fz <= 0.0:   # below the geometric surface (a shading normal far from it)
        return ABSORBED, dx, dy, dz, 0.0, depth, dim + 3
    metal = M.par[inst, 3] > 0.0
    cos_i = min(max(cos_m, 0.0), 1.0)
    n_in = param(M, med[depth - 1], 0, lam) if depth > 0 else 1.0
    sx, sy, sz, rs2, rp2, cr, dr = fx, fy, fz, 0.0, 0.0, 0.0, 0.0
    if pol[ON] != 0.0:
        sx, sy, sz = enter_plane(pol, dx, dy, dz, wmx, wmy, wmz)
        if metal:
            rs2, rp2, cr, dr, _, _, _, _ = stack_mueller(M.layers, 0, 0, False, n_in, M.par[inst, 1],
                                                         M.par[inst, 2], lam if lam > 0.0 else WHITE_NM, cos_i)
        else:
            rs2 = param(M, inst, 0, lam)
            rp2, cr, dr = rs2, -rs2, 0.0
        r = interface_power(pol, rs2, rp2)
    elif metal:
        r = stack_reflectance(M.layers, 0, 0, False, n_in, M.par[inst, 1], M.par[inst, 2],
                              lam if lam > 0.0 else WHITE_NM, cos_i)
    else:
        r = param(M, inst, 0, lam)
    if uniform(key, dim + 2) >= r * g:
        return ABSORBED, dx, dy, dz, 0.0, depth, dim + 3
    if pol[ON] != 0.0:
        leave_plane(pol, rs2, rp2, cr, dr, rx, ry, rz, sx, sy, sz)
    return CONTINUES, rx, ry, rz, 1.0, depth, dim + 3
