"""Spectra: the wavelength grid, V(λ) and the CIE 1931 colour-matching functions, the spectra of lights
and the wavelength-dependent values of materials.

The grid: 360–830 nm in 1 nm steps (`GRID_N` = 471 samples, `LAMBDA_MIN` … `LAMBDA_MAX`), the range
of the CIE tables. Every spectral quantity is tabulated on it and read by linear interpolation
(`grid_value`), so a kernel never evaluates a formula per photon. The CIE tables (V(λ) of CIE 1924,
x̄ ȳ z̄ of CIE 1931 2°) ship in `data/cie_1nm.csv`, taken from colour-science (a test checks them);
K_m = 683 lm/W (pbrt-v4 and colour-science use 683; the SI value is 683.002 at 540 THz).

Light spectra (wire bodies, docs/DESIGN.md):

| body | meaning |
| --- | --- |
| absent | equal energy over 380–780 nm |
| ``{"type": "monochromatic", "nm": λ}`` | one line, λ in [360, 830] nm |
| ``{"type": "blackbody", "kelvin": T}`` | Planck's law, T in [100, 1e5] K |
| ``{"type": "table", "nm": [...], "values": [...]}`` | relative power, linear between the samples, 0 outside |

Material values that may vary with λ: a number, or ``{"nm": [...], "values": [...]}`` (linear between the
samples, the end values held beyond them); a refractive index also as ``{"sellmeier": {"b": [...],
"c_um2": [...]}}`` (n² = 1 + Σ b λ²/(λ² − c), λ in µm) or ``{"table": {"nm": [...], "n": [...]}}``.

The photometric link: a light of luminous flux Φ_v and spectrum S has radiant flux Φ_e = Φ_v / K(S),
with K(S) = K_m ∫V S dλ / ∫S dλ (lm/W, `efficacy`). In the spectral state a photon carries radiant power
(W) and a wavelength; a receiver turns it back into luminous flux with K_m V(λ).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tracer.errors import TracerError
from tracer.jit import njit
from tracer.optics.frames import find_in_cdf

LAMBDA_MIN = 360.0       # nm: first grid sample
LAMBDA_MAX = 830.0       # nm: last grid sample
GRID_N = 471             # samples, 1 nm apart
WHITE_NM = 550.0         # nm: where a white photon's wavelength-dependent value is read (a metal's Fresnel
                         # reflectance; nothing that varies with λ is in a white scene)
KM = 683.0               # lm/W: maximum luminous efficacy (CIE)
EQUAL_ENERGY = (380.0, 780.0)   # nm: the default spectrum of a light
BIN_NM = 5.0             # nm: width of the bins of a spectral answer
N_BINS = 94              # 5 nm bins over 360–830 nm
H_C = 6.62607015e-34 * 2.99792458e8   # J·m: Planck's constant × the speed of light
K_B = 1.380649e-23                    # J/K: Boltzmann's constant

_TABLE = np.loadtxt(Path(__file__).with_name("data") / "cie_1nm.csv", delimiter=",", comments="#",
                    encoding="utf-8")
GRID_NM = _TABLE[:, 0].copy()                 # (471,) nm
V_GRID = np.ascontiguousarray(_TABLE[:, 1])   # (471,) CIE 1924 photopic V(λ)
CMF_GRID = np.ascontiguousarray(_TABLE[:, 2:5])   # (471, 3) CIE 1931 2° x̄, ȳ, z̄
XBAR_GRID = np.ascontiguousarray(CMF_GRID[:, 0])  # (471,) x̄ and z̄ alone, for `grid_value` (ȳ is V)
ZBAR_GRID = np.ascontiguousarray(CMF_GRID[:, 2])
assert GRID_NM.shape == (GRID_N,) and GRID_NM[0] == LAMBDA_MIN and GRID_NM[-1] == LAMBDA_MAX


class SpectrumError(TracerError):
    """A spectrum or spectral value that cannot be used; the message names the field."""


# ---------------------------------------------------------------------------------------- values


def _numbers(v, name: str, where: str, lo: float, hi: float, min_len: int = 1) -> tuple[float, ...]:
    if not isinstance(v, list | tuple) or len(v) < min_len:
        raise SpectrumError(f"{where}: {name!r} must be a list of at least {min_len} numbers, got {v!r}"[:300])
    out = []
    for x in v:
        if isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(x) or not lo <= x <= hi:
            raise SpectrumError(f"{where}: every value of {name!r} must be a finite number in [{lo:g}, {hi:g}], "
                                f"got {x!r}")
        out.append(float(x))
    return tuple(out)


def _samples(body: dict, where: str, values_key: str, lo: float, hi: float) -> tuple[tuple, tuple]:
    extra = set(body) - {"nm", values_key}
    if extra:
        raise SpectrumError(f"{where}: unknown field(s) {sorted(extra)}; a table has 'nm' and {values_key!r}")
    nm = _numbers(body.get("nm"), "nm", where, LAMBDA_MIN, LAMBDA_MAX, 2)
    values = _numbers(body.get(values_key), values_key, where, lo, hi, 2)
    if len(nm) != len(values):
        raise SpectrumError(f"{where}: 'nm' has {len(nm)} samples but {values_key!r} has {len(values)}")
    if any(b <= a for a, b in zip(nm, nm[1:], strict=False)):
        raise SpectrumError(f"{where}: 'nm' must increase strictly")
    return nm, values


@dataclass(frozen=True)
class SpectralTable:
    """A material value sampled at wavelengths `nm` (increasing, in [360, 830]): linear between the
    samples, the end values held beyond them."""

    nm: tuple[float, ...]
    values: tuple[float, ...]

    def grid(self) -> np.ndarray:
        """(GRID_N,) float64: the value at each grid wavelength."""
        return np.interp(GRID_NM, self.nm, self.values)

    def mean(self) -> float:
        return float(self.grid().mean())


@dataclass(frozen=True)
class Sellmeier:
    """A refractive index by Sellmeier's formula: n² = 1 + Σ b_i λ² / (λ² − c_i), λ in µm, c in µm²."""

    b: tuple[float, ...]
    c_um2: tuple[float, ...]

    def at(self, nm) -> np.ndarray:
        l2 = (np.asarray(nm, dtype=np.float64) / 1000.0) ** 2
        n2 = 1.0 + sum(b * l2 / (l2 - c) for b, c in zip(self.b, self.c_um2, strict=True))
        return np.sqrt(n2)

    def grid(self) -> np.ndarray:
        return self.at(GRID_NM)

    def mean(self) -> float:
        return float(self.at(587.56))   # the d line: the index a catalogue quotes


def spectral_value(v, name: str, where: str, lo: float, hi: float):
    """A material value that may depend on λ: a number (returned as float) or a `SpectralTable` whose
    values lie in [lo, hi]. Raises `SpectrumError` naming the field."""
    if isinstance(v, dict):
        nm, values = _samples(v, f"{where}: {name!r}", "values", lo, hi)
        return SpectralTable(nm, values)
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise SpectrumError(f"{where}: {name!r} must be a finite number or a table {{'nm': [...], 'values': [...]}}, "
                            f"got {v!r}"[:300])
    if not lo <= v <= hi:
        raise SpectrumError(f"{where}: {name!r} must be in [{lo:g}, {hi:g}], got {v:g}")
    return float(v)


def ior_value(v, name: str, where: str, lo: float, hi: float):
    """A refractive index: a number in (lo, hi], a `Sellmeier` or an index `SpectralTable`."""
    if isinstance(v, dict) and set(v) == {"sellmeier"} and isinstance(v["sellmeier"], dict):
        s = v["sellmeier"]
        extra = set(s) - {"b", "c_um2"}
        if extra:
            raise SpectrumError(f"{where}: unknown field(s) {sorted(extra)} in {name!r}.sellmeier; "
                                f"it has 'b' and 'c_um2'")
        b = _numbers(s.get("b"), "b", f"{where}: {name}.sellmeier", -100.0, 100.0)
        c = _numbers(s.get("c_um2"), "c_um2", f"{where}: {name}.sellmeier", 0.0, 1e6)
        if len(b) != len(c) or len(b) > 6:
            raise SpectrumError(f"{where}: {name}.sellmeier needs as many 'b' as 'c_um2' terms (1 to 6)")
        sm = Sellmeier(b, c)
        with np.errstate(all="ignore"):
            n_grid = sm.grid()
        if not np.all(np.isfinite(n_grid)) or not np.all((n_grid > lo) & (n_grid <= hi)):
            raise SpectrumError(f"{where}: {name}.sellmeier gives no index in ({lo:g}, {hi:g}] somewhere in "
                                f"{LAMBDA_MIN:g}–{LAMBDA_MAX:g} nm (a pole or n² ≤ 0): check b and c_um2")
        return sm
    if isinstance(v, dict) and set(v) == {"table"} and isinstance(v["table"], dict):
        nm, n = _samples(v["table"], f"{where}: {name}.table", "n", lo, hi)
        if min(n) <= lo:
            raise SpectrumError(f"{where}: every index 'n' in {name}.table must be > {lo:g}")
        return SpectralTable(nm, n)
    if isinstance(v, dict):
        raise SpectrumError(f"{where}: {name!r} must be a number, {{'sellmeier': {{'b': [...], 'c_um2': [...]}}}} or "
                            f"{{'table': {{'nm': [...], 'n': [...]}}}}")
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise SpectrumError(f"{where}: {name!r} must be a finite number, a Sellmeier formula or a table, "
                            f"got {v!r}"[:300])
    if not lo < v <= hi:
        raise SpectrumError(f"{where}: {name!r} must be in ({lo:g}, {hi:g}], got {v:g}")
    return float(v)


def varies(v) -> bool:
    """Whether a material value depends on the wavelength (a table or a formula, not a number)."""
    return hasattr(v, "grid")


def grid_or_value(v):
    """A material value on the grid (GRID_N,) if it varies with λ, else the number itself."""
    return v.grid() if varies(v) else float(v)


def scalar(v) -> float:
    """A material value as one number: itself, or a table's mean over the grid (a formula's d-line value)."""
    return v.mean() if varies(v) else float(v)


# ------------------------------------------------------------------------------------- light spectra


@dataclass(frozen=True)
class Spectrum:
    """A light's relative spectral power: `mono_nm` > 0 for one line (then `power` is zeros), else 0 and
    `power` (GRID_N,) relative W/nm on the grid."""

    mono_nm: float
    power: np.ndarray

    def __hash__(self) -> int:
        return hash((self.mono_nm, self.power.tobytes()))

    def __eq__(self, other) -> bool:
        return isinstance(other, Spectrum) and self.mono_nm == other.mono_nm and np.array_equal(self.power, other.power)


def planck(nm, kelvin: float) -> np.ndarray:
    """Spectral radiance of a black body, W/(m²·sr·m), at wavelengths `nm` (nm)."""
    lam = np.asarray(nm, dtype=np.float64) * 1e-9
    return 2.0 * H_C * 2.99792458e8 / lam ** 5 / np.expm1(H_C / (lam * K_B * kelvin))


def spectrum(body, where: str = "spectrum") -> Spectrum:
    """Validate a light's `spectrum` body (None: equal energy) and tabulate it. Raises `SpectrumError`."""
    if body is None:
        return Spectrum(0.0, ((GRID_NM >= EQUAL_ENERGY[0]) & (GRID_NM <= EQUAL_ENERGY[1])).astype(np.float64))
    if not isinstance(body, dict):
        raise SpectrumError(f"{where}: expected an object with a 'type', got {type(body).__name__}")
    t = body.get("type")
    fields = {"monochromatic": {"nm"}, "blackbody": {"kelvin"}, "table": {"nm", "values"}}
    if t not in fields:
        raise SpectrumError(f"{where}: unknown spectrum type {t!r}; known: {sorted(fields)}")
    extra = set(body) - fields[t] - {"type"}
    if extra:
        raise SpectrumError(f"{where}: unknown field(s) {sorted(extra)} for a {t!r} spectrum")
    if t == "monochromatic":
        (nm,) = _numbers([body.get("nm")], "nm", where, LAMBDA_MIN, LAMBDA_MAX)
        return Spectrum(nm, np.zeros(GRID_N))
    if t == "blackbody":
        (kelvin,) = _numbers([body.get("kelvin")], "kelvin", where, 100.0, 1e5)
        power = planck(GRID_NM, kelvin)
        return Spectrum(0.0, power / power.max())
    nm_s, values = _samples({k: v for k, v in body.items() if k != "type"}, where, "values", 0.0, 1e300)
    power = np.interp(GRID_NM, nm_s, values, left=0.0, right=0.0)
    if not power.sum() > 0:
        raise SpectrumError(f"{where}: the table has no power in {LAMBDA_MIN:g}–{LAMBDA_MAX:g} nm")
    return Spectrum(0.0, power / power.max())


def efficacy(s: Spectrum) -> float:
    """Luminous efficacy of radiation K(S) = K_m ∫V S / ∫S, lm/W (> 0: V > 0 on the whole grid)."""
    if s.mono_nm > 0:
        return KM * float(np.interp(s.mono_nm, GRID_NM, V_GRID))
    return KM * float(np.dot(V_GRID, s.power) / s.power.sum())


def sampling_table(s: Spectrum) -> tuple[np.ndarray, np.ndarray]:
    """How photons draw their wavelength from S: (cdf, f), each (GRID_N,).

    The grid sample i stands for [λ_i − ½, λ_i + ½) nm, drawn with probability p_i from the mixture
    ½ S/ΣS + ½ S V/ΣSV (half the photons where the eye sees them, half where the power is, so that
    neither photometric answers nor spectra or fluorescence pumped in the ultraviolet starve), and the
    photon's weight is multiplied by f_i = (S_i/ΣS) / p_i: unbiased for every quantity. A line has no
    table (zeros).
    """
    if s.mono_nm > 0:
        return np.zeros(GRID_N), np.zeros(GRID_N)
    p_s = s.power / s.power.sum()
    sv = s.power * V_GRID
    p = 0.5 * p_s + 0.5 * sv / sv.sum()
    cdf = np.cumsum(p)
    cdf /= cdf[-1]
    with np.errstate(divide="ignore", invalid="ignore"):
        f = np.where(p > 0, p_s / np.where(p > 0, p, 1.0), 0.0)
    return cdf, f


def chromaticity(power: np.ndarray) -> tuple[float, float]:
    """CIE 1931 xy of a spectral power on the grid (GRID_N,)."""
    xyz = power @ CMF_GRID
    return float(xyz[0] / xyz.sum()), float(xyz[1] / xyz.sum())


def bin_centres() -> np.ndarray:
    """(N_BINS,) nm: centres of the 5 nm bins of a spectral answer (362.5 … 827.5)."""
    return LAMBDA_MIN + BIN_NM * (np.arange(N_BINS) + 0.5)


# ------------------------------------------------------------------------------------------- kernels


@njit(cache=True, error_model="numpy", _nrt=False)
def grid_value(table, lam):
    """Linear interpolation of a grid row `table` (GRID_N,) at λ = `lam` nm (clamped to the grid)."""
    x = min(max(lam - LAMBDA_MIN, 0.0), LAMBDA_MAX - LAMBDA_MIN)
    i = min(int(x), GRID_N - 2)
    f = x - i
    return table[i] * (1.0 - f) + table[i + 1] * f


@njit(cache=True, error_model="numpy", _nrt=False)
def luminous(lam):
    """K_m V(λ), lm/W, at λ nm."""
    return KM * grid_value(V_GRID, lam)


@njit(cache=True, error_model="numpy", _nrt=False)
def grid_wavelength(cdf, u):
    """Draw a wavelength from a cdf over the grid samples (sample i stands for [λ_i − ½, λ_i + ½) nm):
    (λ nm, the sample index); u uniform in [0, 1)."""
    a = find_in_cdf(cdf, 0, GRID_N, u)
    lo = cdf[a - 1] if a > 0 else 0.0
    width = cdf[a] - lo
    t = (u - lo) / width if width > 0.0 else 0.5
    lam = LAMBDA_MIN + a - 0.5 + min(max(t, 0.0), 1.0)
    return min(max(lam, LAMBDA_MIN), LAMBDA_MAX), a


@njit(cache=True, error_model="numpy", _nrt=False)
def sample_grid(cdf, f, u):
    """Draw a wavelength from a `sampling_table` row: (λ nm, weight factor); u uniform in [0, 1)."""
    lam, a = grid_wavelength(cdf, u)
    return lam, f[a]
