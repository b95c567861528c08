"""``mirror``: specular reflection about the (shading) normal, on both sides.

| field | type | unit | range | default |
| --- | --- | --- | --- | --- |
| reflectance | float or table over λ (`tracer.optics.spectra`) | fraction | [0, 1] | required |

A photon is reflected with probability R, absorbed otherwise. Where the mesh has vertex normals the
mirror direction is taken about the interpolated normal (a tessellated curved mirror focuses as the
true surface would), about the facet's where that would send the photon below the surface.
Effects: `specular` (+ `spectral` for a table). Backward estimator: no (a shadow ray cannot find a point
light through it).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit

from tracer.optics.spectra import scalar, varies
from tracer.optics.surfaces.base import ABSORBED, CONTINUES, arrival_normal, bounds, param, reflect_specular
from tracer.rng import uniform

NAME = "mirror"


@dataclass(frozen=True)
class Spec:
    """Reflectance R (fraction of the incident flux reflected specularly)."""

    reflectance: Any = field(metadata=bounds(0.0, 1.0, value="spectral", column=0,
                                             doc="specular reflectance R, fraction (or a table over λ)"))


def row(spec: Spec) -> np.ndarray:
    return np.array([scalar(spec.reflectance), 0.0, 0.0, 0.0])


def effects(spec: Spec) -> tuple[str, ...]:
    return ("specular", "spectral") if varies(spec.reflectance) else ("specular",)


def diffuse_only(spec: Spec) -> bool:
    return False


@njit(cache=True, error_model="numpy", _nrt=False)
def albedo(M, inst):
    return 0.0


@njit(cache=True, error_model="numpy", _nrt=False)
def scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim, lam):
    if uniform(key, dim) >= param(M, inst, 0, lam):
        return ABSORBED, dx, dy, dz, 0.0, depth, dim + 1
    fx, fy, fz = arrival_normal(ngx, ngy, ngz, dx, dy, dz)
    dx, dy, dz = reflect_specular(sa, inst, prim, hu, hv, dx, dy, dz, fx, fy, fz)
    return CONTINUES, dx, dy, dz, 1.0, depth, dim + 1
