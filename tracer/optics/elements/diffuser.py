"""``diffuser``: a thin sheet that transmits and reflects diffusely (opal glass, a diffusing film).

| field | type | unit | range | default |
| --- | --- | --- | --- | --- |
| transmittance | float or table over λ (`tracer.optics.spectra`) | fraction | [0, 1] | required |
| reflectance | float or table over λ | fraction | [0, 1] | 0 |

transmittance + reflectance ≤ 1 (at every wavelength); the rest, A = 1 − T − R, is absorbed. A photon
arriving on either side is transmitted with probability T into a cosine-distributed direction on the far
side (so the transmitted radiance is Lambertian, whatever the incidence), reflected with probability R
into a cosine-distributed direction on its own side, and absorbed otherwise. Both sides behave alike.
Effects: `lambertian` (+ `spectral` for a table). Backward estimator: no (it would have to follow transmission).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tracer.jit import njit
from tracer.optics.frames import sample_cosine
from tracer.optics.polarization import depolarize
from tracer.optics.spectra import grid_or_value, scalar, varies
from tracer.optics.surfaces.base import ABSORBED, CONTINUES, DIFFUSE, TRANSMITS, arrival_normal, bounds, param
from tracer.rng import uniform

NAME = "diffuser"
FLAGS = DIFFUSE | TRANSMITS


@dataclass(frozen=True)
class Spec:
    """Diffuse transmittance T and diffuse reflectance R; T + R at most 1."""

    transmittance: Any = field(metadata=bounds(0.0, 1.0, value="spectral", column=0,
                                               doc="diffuse transmittance T, fraction (or a table over λ)"))
    reflectance: Any = field(default=0.0, metadata=bounds(0.0, 1.0, value="spectral", column=1,
                                                          doc="diffuse reflectance R, fraction (or a table over λ)"))

    def check(self) -> str | None:
        total = float(np.max(grid_or_value(self.transmittance) + grid_or_value(self.reflectance)))
        if total > 1.0 + 1e-12:
            return f"transmittance + reflectance must be at most 1, got {total:g}"
        return None


def row(spec: Spec) -> np.ndarray:
    return np.array([scalar(spec.transmittance), scalar(spec.reflectance), 0.0, 0.0])


def effects(spec: Spec) -> tuple[str, ...]:
    spectral = varies(spec.transmittance) or varies(spec.reflectance)
    return ("lambertian", "spectral") if spectral else ("lambertian",)


def diffuse_only(spec: Spec) -> bool:
    return False



@njit(cache=True, error_model="numpy", _nrt=False)
def scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim, lam, pol):
    u = uniform(key, dim)
    t, r = param(M, inst, 0, lam), param(M, inst, 1, lam)
    fx, fy, fz = arrival_normal(ngx, ngy, ngz, dx, dy, dz)
    if u < t:
        fx, fy, fz = -fx, -fy, -fz      # leave on the far side
    elif u >= t + r:
        return ABSORBED, dx, dy, dz, 0.0, depth, dim + 1
    dx, dy, dz = sample_cosine(fx, fy, fz, uniform(key, dim + 1), uniform(key, dim + 2))
    depolarize(pol)
    return CONTINUES, dx, dy, dz, 1.0, depth, dim + 3
