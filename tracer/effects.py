"""The effect set of a scene: which physics the transport kernel has to compile in.

| effect | called for by |
| --- | --- |
| `lambertian` | always (diffuse reflection is the baseline kernel) |
| `specular` | a `mirror` material, or a `mix` with specular > 0 |
| `fresnel` | a `dielectric` material (Fresnel interfaces, refraction, total internal reflection) |
| `absorption` | a `dielectric` with absorption_per_m > 0 |
| `scattering` | a `dielectric` with scattering_per_m > 0 |

Each effect beyond `lambertian` is a compile-time flag of the kernel (`Flags`): the kernel takes the
flag as an argument that is either `None` (effect off: numba prunes the branch, the code is not even
compiled in) or `True`. Each combination is one cached compiled variant. `force_effects` turns an
effect on in a scene that does not need it, to check that the result does not change.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from tracer.surfaces import DIELECTRIC, MIRROR, MIX, MaterialArrays

EFFECTS = ("lambertian", "specular", "fresnel", "absorption", "scattering")


class EffectError(ValueError):
    """An unknown effect name."""


class Flags(NamedTuple):
    """Kernel flags: None = off (pruned at compile time), True = on."""

    specular: bool | None
    fresnel: bool | None
    absorption: bool | None
    scattering: bool | None


def derive_effects(mats: MaterialArrays, used: np.ndarray | None = None) -> list[str]:
    """The effect set of a material table (only instances in `used`, a boolean mask, when given)."""
    kind, par = mats.kind, mats.par
    if used is not None:
        kind, par = kind[used], par[used]
    out = {"lambertian"}
    if np.any(kind == MIRROR) or np.any((kind == MIX) & (par[:, 1] > 0)):
        out.add("specular")
    diel = kind == DIELECTRIC
    if np.any(diel):
        out.add("fresnel")
        if np.any(par[diel, 1] > 0):
            out.add("absorption")
        if np.any(par[diel, 2] > 0):
            out.add("scattering")
    return [e for e in EFFECTS if e in out]


def with_forced(effects: list[str], force: tuple[str, ...] | list[str]) -> list[str]:
    """`effects` plus the forced ones, in canonical order; unknown names raise `EffectError`."""
    if isinstance(force, str):
        force = (force,)
    unknown = sorted(set(force) - set(EFFECTS))
    if unknown:
        raise EffectError(f"unknown effect(s) {unknown}; known: {list(EFFECTS)}")
    s = set(effects) | set(force)
    return [e for e in EFFECTS if e in s]


def flags_for(effects: list[str]) -> Flags:
    """The kernel flags of an effect set (media imply the Fresnel interface that bounds them)."""
    s = set(effects)
    return Flags(True if "specular" in s else None,
                 True if ("fresnel" in s or "absorption" in s or "scattering" in s) else None,
                 True if "absorption" in s else None,
                 True if "scattering" in s else None)
