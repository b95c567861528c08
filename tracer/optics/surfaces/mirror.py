"""``mirror``: specular reflection about the (shading) normal, on both sides.

| field | type | unit | range | default |
| --- | --- | --- | --- | --- |
| reflectance | float or table over λ (`tracer.optics.spectra`) | fraction | [0, 1] | one of reflectance and metal |
| metal | [n, k]: the metal's complex index n − ik | — | n in (0, 20], k in [0, 50] | one of reflectance and metal |
| coating | thin films on the metal (`tracer.optics.coating`) | — | — | none (needs `metal`) |

A photon is reflected with probability R, absorbed otherwise: R is `reflectance`, or for a `metal` the
Fresnel reflectance of n − ik at the photon's angle (mean of s and p), through the coating's layers where
there is one (transfer matrices at the photon's wavelength; the ambient index is that of the solid the
photon is in, 1 outside every solid). Where the mesh has vertex normals the mirror direction is taken about
the interpolated normal (a tessellated curved mirror focuses as the true surface would), about the
facet's where that would send the photon below the surface.
In a polarized scene the reflection acts with its Mueller matrix: the metal's (s and p amplitudes, with their
phase), or a perfect reflector's scaled by R (S2 and S3 turn over, as at a metal at normal incidence).
Effects: `specular` (+ `spectral` for a table, + `coating` and `spectral` for a coating). Backward
estimator: no (a shadow ray cannot find a point light through it). Limits: the metal's index does not
vary with λ.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tracer.jit import njit
from tracer.optics.coating import Coating, parse_coating
from tracer.optics.polarization import ON, enter_plane, interface_power, leave_plane
from tracer.optics.spectra import WHITE_NM, scalar, varies
from tracer.optics.surfaces.base import (
    ABSORBED,
    CONTINUES,
    SPECULAR,
    MaterialError,
    arrival_normal,
    bounds,
    optional,
    param,
    reflect_specular,
    specular_normal,
)
from tracer.optics.thinfilm import stack_mueller, stack_reflectance
from tracer.rng import uniform

NAME = "mirror"
FLAGS = SPECULAR


def parse_metal(v, name: str, where: str) -> tuple[float, float]:
    """A metal's complex index [n, k] (n − ik); `MaterialError` naming the field."""
    ok = isinstance(v, list | tuple) and len(v) == 2 and all(
        not isinstance(x, bool) and isinstance(x, int | float) and math.isfinite(x) for x in v)
    if not ok or not (0.0 < v[0] <= 20.0 and 0.0 <= v[1] <= 50.0):
        raise MaterialError(f"{where}: {name!r} must be [n, k], the metal's complex index n − ik with n in (0, 20] "
                            f"and k in [0, 50] (aluminium at 550 nm: [0.96, 6.69]), got {v!r}"[:300])
    return float(v[0]), float(v[1])


@dataclass(frozen=True)
class Spec:
    """Reflectance R (fraction reflected specularly), or a metal's complex index with an optional coating."""

    reflectance: Any = field(default=None, metadata=bounds(0.0, 1.0, value="spectral", column=0,
                                                           doc="specular reflectance R, fraction (or a table over λ)"))
    metal: tuple[float, float] | None = field(default=None, metadata=optional(
        parse_metal, "the metal's complex index [n, k] (n − ik), instead of a reflectance"))
    coating: Coating | None = field(default=None, metadata=optional(parse_coating, "thin films on the metal"))

    def check(self) -> str | None:
        if (self.reflectance is None) == (self.metal is None):
            return "give exactly one of 'reflectance' and 'metal'"
        if self.coating is not None and self.metal is None:
            return "a coated mirror needs its 'metal' ([n, k]) under the layers"
        return None


def row(spec: Spec) -> np.ndarray:
    if spec.metal is None:
        return np.array([scalar(spec.reflectance), 0.0, 0.0, 0.0])
    return np.array([0.0, spec.metal[0], spec.metal[1], 1.0])


def effects(spec: Spec) -> tuple[str, ...]:
    if spec.coating is not None:
        return ("specular", "coating", "spectral")
    return ("specular", "spectral") if varies(spec.reflectance) else ("specular",)


def polarizing(spec: Spec) -> tuple[int, float]:
    """A metal reflects s and p apart: one interaction per surface, its largest diattenuation |Rs − Rp| / (Rs + Rp)
    over the angles of incidence (from air), 1 (a bound) under a coating; a perfect reflector acts alike on s and p
    (`tracer.effects`)."""
    if spec.metal is None:
        return 0, 0.0
    if spec.coating is not None:
        return 1, 1.0
    return 1, metal_diattenuation(*spec.metal)


def metal_diattenuation(n: float, k: float) -> float:
    """max over θ of (Rs − Rp) / (Rs + Rp) for the complex index n − ik seen from air (aluminium: 0.139)."""
    eps = complex(n, -k) ** 2
    th = np.linspace(0.0, 0.5 * math.pi, 9001)[:-1]
    c = np.cos(th)
    w = np.sqrt(eps - np.sin(th) ** 2)
    rs = np.abs((c - w) / (c + w)) ** 2
    rp = np.abs((eps * c - w) / (eps * c + w)) ** 2
    return float(np.max(np.abs(rs - rp) / np.maximum(rs + rp, 1e-300)))


def diffuse_only(spec: Spec) -> bool:
    return False



@njit(cache=True, error_model="numpy", _nrt=False)
def scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim, lam, pol):
    fx, fy, fz = arrival_normal(ngx, ngy, ngz, dx, dy, dz)
    metal = M.par[inst, 3] > 0.0
    n_in, snx, sny, snz, cos_i = 1.0, fx, fy, fz, 1.0
    sx, sy, sz, rs2, rp2, cr, dr = fx, fy, fz, 0.0, 0.0, 0.0, 0.0
    if metal or pol[ON] != 0.0:
        n_in = param(M, med[depth - 1], 0, lam) if depth > 0 else 1.0
        snx, sny, snz = specular_normal(sa, inst, prim, hu, hv, fx, fy, fz)
        cos_i = min(max(-(dx * snx + dy * sny + dz * snz), 0.0), 1.0)
    if pol[ON] != 0.0:   # polarized: the Mueller matrix of the metal (under its coating) or of a perfect reflector
        sx, sy, sz = enter_plane(pol, dx, dy, dz, snx, sny, snz)
        if metal:
            rs2, rp2, cr, dr, _, _, _, _ = stack_mueller(M.layers, M.coat[inst, 0], M.coat[inst, 1], False, n_in,
                                                         M.par[inst, 1], M.par[inst, 2],
                                                         lam if lam > 0.0 else WHITE_NM, cos_i)
        else:
            rs2 = param(M, inst, 0, lam)
            rp2, cr, dr = rs2, -rs2, 0.0
        r = interface_power(pol, rs2, rp2)
    elif metal:   # a metal, under its coating if any
        r = stack_reflectance(M.layers, M.coat[inst, 0], M.coat[inst, 1], False, n_in, M.par[inst, 1],
                              M.par[inst, 2], lam if lam > 0.0 else WHITE_NM, cos_i)
    else:
        r = param(M, inst, 0, lam)
    if uniform(key, dim) >= r:
        return ABSORBED, dx, dy, dz, 0.0, depth, dim + 1
    dx, dy, dz = reflect_specular(sa, inst, prim, hu, hv, dx, dy, dz, fx, fy, fz)
    if pol[ON] != 0.0:
        leave_plane(pol, rs2, rp2, cr, dr, dx, dy, dz, sx, sy, sz)
    return CONTINUES, dx, dy, dz, 1.0, depth, dim + 1
