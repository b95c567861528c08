"""Fluorescence inside a dielectric: absorption by spectrum, isotropic re-emission with the emission spectrum.

Body (the dielectric's ``fluorescence`` field):

| field | unit | range | default |
| --- | --- | --- | --- |
| absorption_per_m | 1/m | [0, 1e9], a number or a table over λ | required |
| quantum_yield | photons emitted per photon absorbed | [0, 1] | required |
| emission | a spectrum (`tracer.optics.spectra`: monochromatic, blackbody or table) | — | required |

A photon of wavelength λ meets a fluorescent absorption after a free flight of density σf(λ) exp(−σf t)
(beside the medium's scattering, `homogeneous`). It is re-emitted with probability `quantum_yield`,
isotropically, with a wavelength λ' drawn from the emission spectrum, and its power (W) scales by λ/λ'
(one photon out per photon in: energy hc/λ' for hc/λ); otherwise it is absorbed. Emission spectra are
sampled in proportion to their power (no importance mixture: the emitted photon's wavelength is its own).
Effects: ``fluorescence`` and ``spectral``. Limits: no reabsorption shift of the emission shape with
depth beyond what the traced photons do themselves; the emitted wavelength does not depend on the
absorbed one (Kasha–Vavilov).

Medium row columns (`tracer.optics.media.homogeneous`): 3 σf (table in ``mtab[3]``), 4 quantum yield,
5 the emission line in nm (0 for a spectrum, whose cdf is the table ``mtab[5]``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from tracer.jit import njit
from tracer.optics import spectra
from tracer.optics.surfaces.base import MaterialError

SIGMA_F, QY, EMISSION_NM = 3, 4, 5   # medium row columns


@dataclass(frozen=True)
class Fluorescence:
    """σf (1/m, a number or a `SpectralTable`), quantum yield (photons), emission (`spectra.Spectrum`)."""

    absorption_per_m: Any
    quantum_yield: float
    emission: spectra.Spectrum

    def emission_cdf(self) -> np.ndarray:
        """(GRID_N,) cumulative emission probability over the grid samples (zeros for a line)."""
        if self.emission.mono_nm > 0:
            return np.zeros(spectra.GRID_N)
        c = np.cumsum(self.emission.power)
        return c / c[-1]


def parse_fluorescence(v, name: str, where: str) -> Fluorescence:
    """Validate a fluorescence body; `MaterialError` naming the field."""
    at = f"{where}: {name}"
    if not isinstance(v, dict):
        raise MaterialError(f"{at} must be an object with absorption_per_m, quantum_yield and emission")
    fields = {"absorption_per_m", "quantum_yield", "emission"}
    extra, missing = set(v) - fields, fields - set(v)
    if extra or missing:
        problems = ([f"unknown field(s) {sorted(extra)}"] if extra else []) + (
            [f"missing {sorted(missing)}"] if missing else [])
        raise MaterialError(f"{at}: " + "; ".join(problems))
    qy = v["quantum_yield"]
    if isinstance(qy, bool) or not isinstance(qy, int | float) or not math.isfinite(qy) or not 0 <= qy <= 1:
        raise MaterialError(f"{at}: 'quantum_yield' must be a number in [0, 1] (photons out per photon in), got {qy!r}")
    try:
        sigma = spectra.spectral_value(v["absorption_per_m"], "absorption_per_m", at, 0.0, 1e9)
        emission = spectra.spectrum(v["emission"], f"{at}.emission")
    except spectra.SpectrumError as exc:
        raise MaterialError(str(exc)) from None
    return Fluorescence(sigma, float(qy), emission)


@njit(cache=True, error_model="numpy", _nrt=False)
def reemit(M, mi, lam, u_yield, u_lam):
    """After a fluorescent absorption at λ nm: (alive, λ' nm, power factor λ/λ')."""
    if u_yield >= M.mpar[mi, QY]:
        return False, lam, 0.0
    if M.mpar[mi, EMISSION_NM] > 0.0:
        out = M.mpar[mi, EMISSION_NM]
    else:
        out, _ = spectra.grid_wavelength(M.tables[M.mtab[mi, EMISSION_NM]], u_lam)
    return True, out, lam / out
