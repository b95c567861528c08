"""``mix``: a diffuse and a specular part on one surface (painted metal, glossy plastic), both sides.

| field | type | unit | range | default |
| --- | --- | --- | --- | --- |
| diffuse | float | fraction | [0, 1] | required |
| specular | float | fraction | [0, 1] | required |

diffuse + specular ≤ 1. A photon is reflected diffusely with probability ρd, specularly with ρs, and
absorbed otherwise. Effects: `lambertian`, and `specular` where ρs > 0. Backward estimator: where
ρs = 0 (then it is a Lambertian surface of albedo ρd).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from tracer.jit import njit
from tracer.optics.frames import sample_cosine
from tracer.optics.polarization import ON, depolarize, enter_plane, leave_plane
from tracer.optics.surfaces.base import ABSORBED, CONTINUES, DIFFUSE, SPECULAR, arrival_normal, bounds, reflect_specular
from tracer.rng import uniform

NAME = "mix"
FLAGS = DIFFUSE | SPECULAR


@dataclass(frozen=True)
class Spec:
    """Diffuse reflectance ρd and specular reflectance ρs; their sum at most 1."""

    diffuse: float = field(metadata=bounds(0.0, 1.0, doc="diffuse reflectance ρd, fraction"))
    specular: float = field(metadata=bounds(0.0, 1.0, doc="specular reflectance ρs, fraction"))

    def check(self) -> str | None:
        if self.diffuse + self.specular > 1.0 + 1e-12:
            return f"diffuse + specular must be at most 1, got {self.diffuse + self.specular:g}"
        return None


def row(spec: Spec) -> np.ndarray:
    return np.array([spec.diffuse, spec.specular, 0.0, 0.0])


def effects(spec: Spec) -> tuple[str, ...]:
    return ("lambertian", "specular") if spec.specular > 0 else ("lambertian",)


def diffuse_only(spec: Spec) -> bool:
    return spec.specular == 0.0


@njit(cache=True, error_model="numpy", _nrt=False)
def albedo(M, inst):
    return M.par[inst, 0]


@njit(cache=True, error_model="numpy", _nrt=False)
def scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim, lam, pol):
    u = uniform(key, dim)
    rd, rs = M.par[inst, 0], M.par[inst, 1]
    fx, fy, fz = arrival_normal(ngx, ngy, ngz, dx, dy, dz)
    if u < rd:
        dx, dy, dz = sample_cosine(fx, fy, fz, uniform(key, dim + 1), uniform(key, dim + 2))
        depolarize(pol)
        return CONTINUES, dx, dy, dz, 1.0, depth, dim + 3
    if u < rd + rs:
        ox, oy, oz = reflect_specular(sa, inst, prim, hu, hv, dx, dy, dz, fx, fy, fz)
        if pol[ON] != 0.0:   # a perfect reflector's Mueller matrix (the weight is chosen by ρs already)
            sx, sy, sz = enter_plane(pol, dx, dy, dz, ox, oy, oz)
            leave_plane(pol, 1.0, 1.0, -1.0, 0.0, ox, oy, oz, sx, sy, sz)
        dx, dy, dz = ox, oy, oz
        return CONTINUES, dx, dy, dz, 1.0, depth, dim + 1
    return ABSORBED, dx, dy, dz, 0.0, depth, dim + 1
