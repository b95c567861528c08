"""``black``: absorbs every photon that reaches it.

| field | type | unit | range | default |
| --- | --- | --- | --- | --- |
| (none) | | | | |

Effects: none beyond the baseline. Backward estimator: yes (a diffuse surface of albedo 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tracer.jit import njit
from tracer.optics.surfaces.base import ABSORBED, N_PAR

NAME = "black"
FLAGS = 0   # absorbs everything


@dataclass(frozen=True)
class Spec:
    """A black surface has no parameters."""


def row(spec: Spec) -> np.ndarray:
    return np.zeros(N_PAR)


def effects(spec: Spec) -> tuple[str, ...]:
    return ()


def diffuse_only(spec: Spec) -> bool:
    return True



@njit(cache=True, error_model="numpy", _nrt=False)
def scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim, lam, pol):
    return ABSORBED, dx, dy, dz, 0.0, depth, dim
