"""Thin-film coatings on a surface: the wire body, its validation, and the reflectance a kernel asks for.

Body (on a ``dielectric`` or a ``mirror``): ``{"layers": [{"ior": 1.38, "thickness_nm": 99.64}, ...]}``, the
layers outermost first (the first touches the air, the last the substrate).

| field | unit | range |
| --- | --- | --- |
| layers | — | 1 to `MAX_LAYERS` layers |
| layers[].ior | — | [1, 5], real (a lossless dielectric film) |
| layers[].thickness_nm | nm | [0, 1e5] |

The coating covers every face of the solid it is on. The reflectance is the transfer-matrix method's
(`tracer.optics.thinfilm`), per wavelength and angle, the mean of s and p (the photon carries no
polarization in this state); light arriving from the substrate side crosses the layers innermost first.
A coating needs the photon's wavelength: it calls for the effects ``coating`` and ``spectral``. Limits:
coherent films (thickness ≪ the coherence length of the light; a layer of 1e5 nm is at the edge), real
indices without dispersion.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tracer.jit import njit
from tracer.optics.surfaces.base import MaterialError
from tracer.optics.thinfilm import stack_reflectance

MAX_LAYERS = 200


@dataclass(frozen=True)
class Coating:
    """layers: ((n, thickness nm), ...), outermost first."""

    layers: tuple[tuple[float, float], ...]


def parse_coating(v, name: str, where: str) -> Coating:
    """Validate a coating body; raises `MaterialError` naming the layer and the field."""
    if not isinstance(v, dict) or set(v) != {"layers"}:
        raise MaterialError(f"{where}: {name!r} must be {{'layers': [{{'ior': n, 'thickness_nm': d}}, ...]}}, "
                            f"got {v!r}"[:300])
    layers = v["layers"]
    if not isinstance(layers, list) or not 1 <= len(layers) <= MAX_LAYERS:
        raise MaterialError(f"{where}: {name}.layers must be a list of 1 to {MAX_LAYERS} layers")
    out = []
    for i, layer in enumerate(layers):
        at = f"{where}: {name}.layers[{i}]"
        if not isinstance(layer, dict) or set(layer) != {"ior", "thickness_nm"}:
            raise MaterialError(f"{at} must be {{'ior': n, 'thickness_nm': d}}, got {layer!r}"[:300])
        n, d = layer["ior"], layer["thickness_nm"]
        for key, x, lo, hi in (("ior", n, 1.0, 5.0), ("thickness_nm", d, 0.0, 1e5)):
            if isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(x) or not lo <= x <= hi:
                raise MaterialError(f"{at}: {key!r} must be a number in [{lo:g}, {hi:g}], got {x!r}")
        out.append((float(n), float(d)))
    return Coating(tuple(out))


@njit(cache=True, error_model="numpy", _nrt=False)
def coated_reflectance(M, inst, from_outside, n1, n2, k2, lam, cos_i):
    """Unpolarized reflectance of the coating of `inst` between indices n1 (where the photon is) and
    n2 − i k2 (beyond), at λ nm and cos θ_i; `from_outside`: the photon arrives on the coating's air side."""
    return stack_reflectance(M.layers, M.coat[inst, 0], M.coat[inst, 1], not from_outside, n1, n2, k2, lam, cos_i)
