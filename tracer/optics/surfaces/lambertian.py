"""``lambertian``: ideal diffuse reflection on both sides.

| field | type | unit | range | default |
| --- | --- | --- | --- | --- |
| reflectance | float or table over λ (`tracer.optics.spectra`) | fraction | [0, 1] | required |

A photon is reflected with probability ρ (keeping its weight) into a cosine-distributed direction on
the side it arrived from, and absorbed otherwise. Effects: `lambertian` (+ `spectral` for a table).
Backward estimator: yes, for a reflectance that does not vary with λ.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tracer.jit import njit
from tracer.optics.frames import sample_cosine
from tracer.optics.polarization import depolarize
from tracer.optics.spectra import scalar, varies
from tracer.optics.surfaces.base import ABSORBED, CONTINUES, DIFFUSE, N_PAR, arrival_normal, bounds, param
from tracer.rng import uniform

NAME = "lambertian"
FLAGS = DIFFUSE


@dataclass(frozen=True)
class Spec:
    """Reflectance ρ (fraction of the incident flux reflected diffusely)."""

    reflectance: Any = field(metadata=bounds(0.0, 1.0, value="spectral", column=0,
                                             doc="diffuse reflectance ρ, fraction (or a table over λ)"))


def row(spec: Spec) -> np.ndarray:
    return np.array([scalar(spec.reflectance), 0.0, 0.0, 0.0][:N_PAR])


def effects(spec: Spec) -> tuple[str, ...]:
    return ("lambertian", "spectral") if varies(spec.reflectance) else ("lambertian",)


def diffuse_only(spec: Spec) -> bool:
    return not varies(spec.reflectance)


@njit(cache=True, error_model="numpy", _nrt=False)
def albedo(M, inst):
    return M.par[inst, 0]


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim, lam, pol):
    return scatter_rho(param(M, inst, 0, lam), dx, dy, dz, ngx, ngy, ngz, depth, key, dim, pol)


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def scatter_rho(rho, dx, dy, dz, ngx, ngy, ngz, depth, key, dim, pol):
    """`scatter` for a reflectance given as a number (an element's features, `tracer.elements.features.FRHO`)."""
    if uniform(key, dim) >= rho:
        return ABSORBED, dx, dy, dz, 0.0, depth, dim + 1
    fx, fy, fz = arrival_normal(ngx, ngy, ngz, dx, dy, dz)
    dx, dy, dz = sample_cosine(fx, fy, fz, uniform(key, dim + 1), uniform(key, dim + 2))
    depolarize(pol)
    return CONTINUES, dx, dy, dz, 1.0, depth, dim + 3
