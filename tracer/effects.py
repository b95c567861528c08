"""The effect set of a scene, derived here and only here, and the photon state it calls for.

| effect | called for by |
| --- | --- |
| `lambertian` | always (diffuse reflection is the baseline; a `diffuser` needs nothing more) |
| `specular` | a `mirror` material, or a `mix` with specular > 0 |
| `fresnel` | a `dielectric` material (Fresnel interfaces, refraction, total internal reflection) |
| `absorption` | a `dielectric` with absorption_per_m > 0 |
| `scattering` | a `dielectric` with scattering_per_m > 0 |
| `spectral` | any value that depends on the wavelength (below), or a query that observes the spectrum |
| `dispersion` | a `dielectric` whose `ior` is a Sellmeier formula or a table |
| `coating` | a `dielectric` with thin films |
| `fluorescence` | a `dielectric` that fluoresces |
| `mie` | a `dielectric` holding `particles` (Mie scattering, `tracer.optics.mie`) |
| `polarization` | a `polarizer` or `retarder`, a polarized light, or a query that observes Stokes |

Each kind declares its effects (`effects(spec)` in its module, `tracer/optics/`); this module gathers
them. The effects above change no compiled code: they are branches on data (a photon meets a mirror
only where there is one), which the transport benchmark measured to cost nothing where unused. What a
photon *carries* does change the kernel (Mitsuba's variants): `photon_state(effects)` names it, and
`tracer.transport.forward.forward_kernel(state)` is the one factory of kernels. Every effect listed today
up to `scattering` needs only a weight, the state ``"white"``; `spectral` (implied by `dispersion`, `coating`
`fluorescence` and `mie`) needs a wavelength, the state ``"spectral"``; `polarization` needs a Stokes vector and
its frame (`tracer.optics.polarization`), the state ``"polarized"`` (``"polarized-spectral"`` with both). A
light's spectrum alone does not call for a wavelength: in a grey scene the luminous answer is exact without it.
`with_forced` turns effects on in a scene that does not need them (the answer must not change).
"""

from __future__ import annotations

from collections.abc import Iterable

from tracer.errors import TracerError
from tracer.optics.surfaces.dispatch import effects_of, material_spec

EFFECTS = ("lambertian", "specular", "fresnel", "absorption", "scattering", "spectral", "dispersion", "coating",
           "fluorescence", "mie", "polarization")
NEEDS_WAVELENGTH = ("dispersion", "coating", "fluorescence", "mie")
PHOTON_STATES = ("white", "spectral", "polarized", "polarized-spectral")


class EffectError(TracerError):
    """An unknown effect name."""


def canonical(effects: Iterable[str]) -> list[str]:
    """The effects in `EFFECTS` order; unknown names raise `EffectError`."""
    s = set(effects)
    unknown = sorted(s - set(EFFECTS))
    if unknown:
        raise EffectError(f"unknown effect(s) {unknown}; known: {list(EFFECTS)}")
    return [e for e in EFFECTS if e in s]


def derive_effects(materials: Iterable, lights: Iterable[dict] = ()) -> list[str]:
    """The effect set of a scene from its materials (bodies or specs), as their kinds declare it, and its light
    bodies (a polarized light calls for `polarization`).

    Raises `tracer.optics.surfaces.base.MaterialError` for an invalid material body.
    """
    polarized = {"polarization"} if any(isinstance(b, dict) and b.get("polarization") for b in lights) else set()
    return canonical(effects_of(material_spec(m) for m in materials) | polarized)


def with_forced(effects: list[str], force: tuple[str, ...] | list[str] | str) -> list[str]:
    """`effects` plus the forced ones, in canonical order; unknown names raise `EffectError`."""
    if isinstance(force, str):
        force = (force,)
    out = set(effects) | set(force)
    if out & set(NEEDS_WAVELENGTH):
        out.add("spectral")
    return canonical(out)


def photon_state(effects: list[str]) -> str:
    """What a photon must carry for this effect set (`PHOTON_STATES`): a weight (``"white"``), and a wavelength
    (``"spectral"``), a Stokes vector (``"polarized"``) or both (``"polarized-spectral"``)."""
    e = set(canonical(effects))
    if "polarization" in e:
        return "polarized-spectral" if "spectral" in e else "polarized"
    return "spectral" if "spectral" in e else "white"
