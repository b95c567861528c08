"""Mie scattering by spheres suspended in a dielectric: the wire body, the tables a kernel reads, their cache.

Body (a ``dielectric``'s ``particles`` field): ``{"radius_um": 0.5, "ior": [1.59, 0.0], "number_per_m3": 1e15}``.

| field | unit | range | default |
| --- | --- | --- | --- |
| radius_um | µm | [1e-4, 1000] (`MIN_RADIUS_UM`); the size parameter x = 2π r n_host/λ at most `X_MAX` | required |
| ior | [n, k]: the sphere's index n − ik | n in (0, 10], k in [0, 10] (k > 0 absorbs) | required |
| number_per_m3 | 1/m³ | (0, 1e30]; σ_ext = N C_ext at most `SIGMA_MAX` 1/m at every λ | required |

The two limits that need the host's index (x and σ_ext) are checked by `mie_table`, which raises
`MaterialError` naming the field; `parse_particles` checks the rest. The host is real (non-absorbing
between the spheres); the spheres scatter independently (single scattering per event, no dependent
scattering at high volume fraction).

Optics at a vacuum wavelength λ: relative index m = (n − ik)/n_host(λ), size parameter x = 2π r n_host(λ)/λ;
efficiencies Q from the Mie coefficients a_n, b_n of `miepython` (Bohren & Huffman 4.53, 4.61, 4.62; g as
in B&H §4.5), cross-sections C = Q π r², coefficients σ = N C in 1/m. They are computed at the `N_MIE` = 95
wavelengths `MIE_NM` (360, 365, …, 830 nm) and interpolated linearly to the 1 nm grid of
`tracer.optics.spectra` (so σ on the grid never exceeds the samples' largest). Resonance ripple of large
spheres finer than 5 nm is therefore not resolved (it averages out over any real size spread).

Angular tables, one per `MIE_NM` sample, on `N_MU` = 1024 fixed nodes μ = cos θ (`MU`, ascending from −1 to 1):
θ = 0, 256 nodes log-spaced over [1e-5, 0.05] rad (the forward peak, width ~1/x), then uniform steps of
≈ 4e-3 rad to π/2 and on to π (μ = 0 exactly a node). Scattering-matrix elements (B&H 4.77, with B&H's
amplitudes S1, S2 of 4.74, time factor exp(−iωt); `miepython.S1_S2` returns their complex conjugates):

    S11 = (|S2|² + |S1|²)/2,  S12 = (|S2|² − |S1|²)/2,  S33 = Re(S2 S1*),  S34 = Im(S2 S1*)

and the Mueller matrix of one scattering, acting on Stokes vectors referred to the scattering plane (∥, ⊥), is
S11 [[1, s12, 0, 0], [s12, 1, 0, 0], [0, 0, s33, s34], [0, 0, −s34, s33]] with s_ij = S_ij/S11; for a sphere
s12² + s33² + s34² = 1. In `tracer.optics.polarization`'s terms (frame x = s, the normal of the scattering
plane; exp(iωt) amplitudes) it is `apply_interface`'s matrix with A = 1 − s12, B = 1 + s12, C = s33, D = s34
per unit S11 (derived, not tested here). `mie_sample_mu` draws μ from S11 alone, exact for unpolarized light;
a polarized photon, with φ uniform, must also take `apply_interface`'s return value 1 − s12·s1 as a weight
factor (its mean over φ is 1). The phase function is S11 normalised: cdf(μ) = ∫₋₁^μ S11 dμ' / ∫₋₁^1 S11 dμ',
integrated by the trapezoid rule on sub-samples at most `SUB_DTHETA_X`/x rad apart (so the cdf at the nodes
resolves the ripple of spheres up to x = `X_MAX`; the table's mean μ agrees with g to ~1e-4). Between nodes μ
is uniform (linear in the cdf); the ratios s12, s33, s34 are the point values at the nodes, linear between
them (for x ≳ 300 they oscillate faster than the nodes and the table holds samples of them; a linear blend of
two sphere matrices is a valid, slightly depolarizing, Mueller matrix). Where S11 vanishes at every node
(zero coefficients, an underflow) the table is isotropic with s12 = s34 = 0, s33 = 1; an index-matched sphere
(m = 1) has σ of rounding size (~1e-30 1/m).

Packed layout for the kernels (`packed`): float64 (`PACKED_ROWS`, `N_MU`); row `MU_ROW` = 0 holds `MU`; the
sample i (λ = `MIE_NM`[i]) owns rows 1 + `ROWS_PER_NM`·i + (`CDF`, `S12`, `S33`, `S34`). The kernels use the
sample nearest the photon's λ (5 nm apart), not a blend of two.

Cache: tables are built once per (particles, host index) and kept in memory (`MEMORY_ENTRIES` most recent)
and on disk, one ``mie-<sha256>.npz`` per table in ``$LUMENLINK_OPTICS_CACHE`` or else
``<numba cache dir>/optics``; the name is the SHA-256 of `TABLE_VERSION` and the inputs. Writes are atomic
(temporary file + rename); a file that does not open, holds other inputs or fails its digest is ignored and
rebuilt; an unwritable directory is skipped silently. Build time (one core, measured): 0.1 s for r = 0.5 µm,
0.2 s for 5 µm, 1 s for 50 µm, 30 s for 1000 µm in n_host = 1 (x = 1.7e4 at 360 nm), 70 s at x = `X_MAX`
(cost ∝ x²); a disk hit takes ~10 ms. miepython is needed to build, not to load.
"""

from __future__ import annotations

import hashlib
import math
import os
import tempfile
import threading
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from tracer.jit import njit
from tracer.optics.frames import find_in_cdf
from tracer.optics.spectra import GRID_N, GRID_NM, LAMBDA_MAX, LAMBDA_MIN
from tracer.optics.surfaces.base import MaterialError

MIE_STEP_NM = 5.0                                      # nm between angular tables
MIE_NM = np.arange(LAMBDA_MIN, LAMBDA_MAX + 0.5, MIE_STEP_NM)   # (N_MIE,) nm: 360, 365, …, 830
N_MIE = 95
N_MU = 1024                  # angular nodes per table
ROWS_PER_NM = 4              # packed rows per sample: cdf, s12, s33, s34
MU_ROW = 0                   # packed row of the μ nodes
CDF, S12, S33, S34 = 0, 1, 2, 3   # row offsets inside a sample's block
PACKED_ROWS = 1 + N_MIE * ROWS_PER_NM
MIN_RADIUS_UM = 1e-4         # µm: 0.1 nm, an atom; smaller radii underflow the Mie series
X_MAX = 3.0e4                # largest size parameter built (cost ∝ x², see module docstring)
SIGMA_MAX = 1e9              # 1/m: largest extinction coefficient
SUB_DTHETA_X = 2.0           # sub-samples at most 2/x rad apart inside a node interval
TABLE_VERSION = "mie-1"      # part of every cache key: change it when the tables change
MEMORY_ENTRIES = 16
assert MIE_NM.shape == (N_MIE,)


def _theta_nodes() -> np.ndarray:
    """(N_MU,) rad, descending from π to 0: the table's angles (μ ascending)."""
    n_fwd, th_fwd = 256, 0.05
    n_mid = (N_MU - 1 - n_fwd) // 2
    n_back = N_MU - 1 - n_fwd - n_mid
    th = np.concatenate([[0.0], np.geomspace(1e-5, th_fwd, n_fwd),
                         np.linspace(th_fwd, math.pi / 2, n_mid + 1)[1:],
                         np.linspace(math.pi / 2, math.pi, n_back + 1)[1:]])
    return th[::-1].copy()


THETA = _theta_nodes()
MU = np.cos(THETA)           # (N_MU,) ascending, −1 … 1, with 0 exactly at θ = π/2
MU[0], MU[-1] = -1.0, 1.0
MU[np.argmin(np.abs(THETA - math.pi / 2))] = 0.0
assert THETA.shape == (N_MU,) and np.all(np.diff(MU) > 0)


# ------------------------------------------------------------------------------------------ the body


@dataclass(frozen=True)
class Particles:
    """Spheres of radius `radius_um` (µm) and index n − ik, `number_per_m3` of them per m³."""

    radius_um: float
    n: float
    k: float
    number_per_m3: float


def _number(v, key: str, at: str, lo: float, hi: float, lo_open: bool) -> float:
    ok = not isinstance(v, bool) and isinstance(v, int | float) and math.isfinite(v)
    if not ok or not (lo < v if lo_open else lo <= v) or not v <= hi:
        interval = f"{'(' if lo_open else '['}{lo:g}, {hi:g}]"
        raise MaterialError(f"{at}: {key!r} must be a finite number in {interval}, got {v!r}"[:300])
    return float(v)


def parse_particles(v, name: str, where: str) -> Particles:
    """Validate a particles body; `MaterialError` naming the field (see the module's table)."""
    at = f"{where}: {name}"
    if not isinstance(v, dict):
        raise MaterialError(f"{at} must be an object {{'radius_um': r, 'ior': [n, k], 'number_per_m3': N}}, "
                            f"got {v!r}"[:300])
    fields = {"radius_um", "ior", "number_per_m3"}
    extra, missing = set(v) - fields, fields - set(v)
    if extra or missing:
        problems = ([f"unknown field(s) {sorted(extra)}"] if extra else []) + (
            [f"missing {sorted(missing)}"] if missing else [])
        raise MaterialError(f"{at}: " + "; ".join(problems) + "; the fields are 'radius_um', 'ior', 'number_per_m3'")
    r = _number(v["radius_um"], "radius_um", at, MIN_RADIUS_UM, 1000.0, lo_open=False)
    ior = v["ior"]
    if not isinstance(ior, list | tuple) or len(ior) != 2:
        raise MaterialError(f"{at}: 'ior' must be [n, k] (the index n − ik), got {ior!r}"[:300])
    n = _number(ior[0], "ior[0] (n)", at, 0.0, 10.0, lo_open=True)
    k = _number(ior[1], "ior[1] (k)", at, 0.0, 10.0, lo_open=False)
    number = _number(v["number_per_m3"], "number_per_m3", at, 0.0, 1e30, lo_open=True)
    return Particles(r, n, k, number)


# ------------------------------------------------------------------------------------------ Mie theory


def _coefficients(m_rel: complex, x: float) -> tuple[np.ndarray, np.ndarray]:
    """B&H's a_n, b_n (n = 1 … N, Wiscombe's N), each (N,) complex128, from miepython (imported here: only
    building a table needs it)."""
    try:
        import miepython
    except ImportError as exc:
        raise ImportError("Mie tables need the package miepython (pip install miepython)") from exc
    a, b = miepython.coefficients(complex(m_rel), float(x))
    return np.asarray(a, dtype=np.complex128), np.asarray(b, dtype=np.complex128)


def _efficiencies_ab(a: np.ndarray, b: np.ndarray, x: float) -> tuple[float, float, float]:
    """(Q_ext, Q_sca, g) from the coefficients: B&H 4.61, 4.62 and the asymmetry sum of §4.5."""
    n = np.arange(1, a.shape[0] + 1, dtype=np.float64)
    qext = 2.0 / x**2 * float(np.sum((2 * n + 1) * (a + b).real))
    qsca = 2.0 / x**2 * float(np.sum((2 * n + 1) * (np.abs(a) ** 2 + np.abs(b) ** 2)))
    n1 = n[:-1]
    gq = 4.0 / x**2 * float(np.sum(n1 * (n1 + 2) / (n1 + 1) * (a[:-1] * np.conj(a[1:]) + b[:-1] * np.conj(b[1:])).real)
                            + np.sum((2 * n + 1) / (n * (n + 1)) * (a * np.conj(b)).real))
    return qext, qsca, (gq / qsca if qsca > 0.0 else 0.0)


def efficiencies(m_rel: complex, x: float) -> tuple[float, float, float]:
    """(Q_ext, Q_sca, g) of a sphere of relative index m_rel = n − ik (k ≥ 0) and size parameter x."""
    return _efficiencies_ab(*_coefficients(m_rel, x), x)


@njit(cache=True)
def amplitude_sums(a, b, mu):
    """B&H 4.74: S1, S2 (each (len(mu),) complex128) at the cosines `mu`; π_n, τ_n by upward recurrence
    (B&H 4.47), the angle loop innermost so that it vectorizes."""
    m = mu.shape[0]
    s1r, s1i, s2r, s2i = np.zeros(m), np.zeros(m), np.zeros(m), np.zeros(m)
    pi_prev, pi_n = np.zeros(m), np.ones(m)
    for n in range(1, a.shape[0] + 1):
        f = (2.0 * n + 1.0) / (n * (n + 1.0))
        ar, ai, br, bi = f * a[n - 1].real, f * a[n - 1].imag, f * b[n - 1].real, f * b[n - 1].imag
        c1, c2 = (2.0 * n + 1.0) / n, (n + 1.0) / n
        for j in range(m):
            p, q, c = pi_n[j], pi_prev[j], mu[j]
            t = n * c * p - (n + 1.0) * q
            s1r[j] += ar * p + br * t
            s1i[j] += ai * p + bi * t
            s2r[j] += ar * t + br * p
            s2i[j] += ai * t + bi * p
            pi_prev[j] = p
            pi_n[j] = c1 * c * p - c2 * q
    return s1r + 1j * s1i, s2r + 1j * s2i


def amplitudes(m_rel: complex, x: float, mu) -> tuple[np.ndarray, np.ndarray]:
    """B&H's amplitudes S1, S2 (complex128, shaped like `mu`) at cosines `mu`; m_rel = n − ik, k ≥ 0."""
    mu = np.ascontiguousarray(mu, dtype=np.float64)
    s1, s2 = amplitude_sums(*_coefficients(m_rel, x), mu.ravel())
    return s1.reshape(mu.shape), s2.reshape(mu.shape)


def mueller_ratios(s1: np.ndarray, s2: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(S11, s12, s33, s34) from B&H amplitudes (see the module docstring); ratios 0, 1, 0 where S11 = 0."""
    i1, i2 = np.abs(s1) ** 2, np.abs(s2) ** 2
    s11 = 0.5 * (i1 + i2)
    z = s2 * np.conj(s1)
    ok = s11 > 0.0
    inv = 1.0 / np.where(ok, s11, 1.0)
    return (s11, np.where(ok, 0.5 * (i2 - i1) * inv, 0.0), np.where(ok, z.real * inv, 1.0),
            np.where(ok, z.imag * inv, 0.0))


def _angular(a: np.ndarray, b: np.ndarray, x: float) -> tuple[np.ndarray, ...]:
    """One sample's (cdf, s12, s33, s34), each (N_MU,), on the nodes `MU`."""
    dth = np.diff(THETA)                                     # negative: θ descends
    per = np.maximum(1, np.ceil(np.abs(dth) * x / SUB_DTHETA_X)).astype(np.int64)
    start = np.concatenate([[0], np.cumsum(per)])            # node j is sub-sample start[j]
    owner = np.repeat(np.arange(N_MU - 1), per)
    frac = (np.arange(start[-1]) - start[owner]) / per[owner]
    mu = np.cos(np.append(THETA[owner] + frac * dth[owner], THETA[-1]))
    mu[start] = MU
    s1, s2 = amplitude_sums(a, b, mu)
    s11, s12, s33, s34 = mueller_ratios(s1, s2)
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (s11[1:] + s11[:-1]) * np.diff(mu))])
    total = cum[-1]
    if not (np.isfinite(total) and total > 0.0):             # no scattering: isotropic, unpolarizing
        return 0.5 * (MU + 1.0), np.zeros(N_MU), np.ones(N_MU), np.zeros(N_MU)
    cdf = cum[start] / total
    cdf[-1] = 1.0
    return cdf, s12[start], s33[start], s34[start]


# ------------------------------------------------------------------------------------------ the tables


class MieTable(NamedTuple):
    """Mie optics of one particle medium (read-only arrays).

    sigma_ext, sigma_sca : (GRID_N,) float64, 1/m — N C_ext and N C_sca on the 1 nm grid.
    g : (GRID_N,) float64 — asymmetry parameter on the grid.
    mu : (N_MU,) float64 — the angular nodes `MU`, ascending.
    cdf : (N_MIE, N_MU) float64 — cumulative phase function at the nodes, per `MIE_NM` sample (0 … 1).
    s12, s33, s34 : (N_MIE, N_MU) float64 — S12/S11, S33/S11, S34/S11 at the nodes.
    """

    sigma_ext: np.ndarray
    sigma_sca: np.ndarray
    g: np.ndarray
    mu: np.ndarray
    cdf: np.ndarray
    s12: np.ndarray
    s33: np.ndarray
    s34: np.ndarray


def _size_parameters(p: Particles, host: np.ndarray) -> np.ndarray:
    """(N_MIE,) x = 2π r n_host/λ at the samples (r µm, λ nm)."""
    n_host = host[(MIE_NM - LAMBDA_MIN).astype(np.int64)]
    return 2.0 * math.pi * p.radius_um * n_host / (MIE_NM * 1e-3)


def _check_size(p: Particles, host: np.ndarray, where: str) -> None:
    x = _size_parameters(p, host)
    i = int(np.argmax(x))
    if x[i] > X_MAX:
        n_host = host[int(MIE_NM[i] - LAMBDA_MIN)]
        r_max = X_MAX * MIE_NM[i] * 1e-3 / (2.0 * math.pi * n_host)
        raise MaterialError(f"{where}: 'radius_um' = {p.radius_um:g} µm gives a size parameter 2πr·n/λ of {x[i]:.4g} "
                            f"at {MIE_NM[i]:g} nm in this host (n = {n_host:.4g}); Mie tables are built up to "
                            f"x = {X_MAX:g}, a radius of at most {r_max:.4g} µm here")


def _build(p: Particles, host: np.ndarray, where: str) -> MieTable:
    with np.errstate(all="ignore"):   # a series that over- or underflows gives a non-finite Q: refused below
        return _build_table(p, host, where)


def _build_table(p: Particles, host: np.ndarray, where: str) -> MieTable:
    area = math.pi * (p.radius_um * 1e-6) ** 2              # m²
    xs = _size_parameters(p, host)
    c_ext, c_sca, g = np.zeros(N_MIE), np.zeros(N_MIE), np.zeros(N_MIE)
    rows = np.zeros((4, N_MIE, N_MU))
    for i, (lam, x) in enumerate(zip(MIE_NM, xs, strict=True)):
        m_rel = complex(p.n, -p.k) / host[int(lam - LAMBDA_MIN)]
        a, b = _coefficients(m_rel, x)
        qext, qsca, g[i] = _efficiencies_ab(a, b, x)
        if not (math.isfinite(qext) and math.isfinite(qsca)):
            raise MaterialError(f"{where}: no Mie solution for ior = [{p.n:g}, {p.k:g}], radius {p.radius_um:g} µm "
                                f"at {lam:g} nm")
        c_ext[i], c_sca[i] = qext * area, qsca * area
        if p.number_per_m3 * c_ext[i] > SIGMA_MAX:
            n_max = SIGMA_MAX / c_ext[i]
            raise MaterialError(f"{where}: 'number_per_m3' = {p.number_per_m3:g} gives an extinction coefficient of "
                                f"{p.number_per_m3 * c_ext[i]:.3g} 1/m at {lam:g} nm (Q_ext = {qext:.4g}, radius "
                                f"{p.radius_um:g} µm); at most {SIGMA_MAX:g} 1/m is supported: N ≤ {n_max:.3g} per m³")
        for r, row in enumerate(_angular(a, b, x)):
            rows[r, i] = row
    return MieTable(sigma_ext=p.number_per_m3 * np.interp(GRID_NM, MIE_NM, c_ext),
                    sigma_sca=p.number_per_m3 * np.interp(GRID_NM, MIE_NM, c_sca),
                    g=np.interp(GRID_NM, MIE_NM, g), mu=MU.copy(), cdf=rows[CDF], s12=rows[S12],
                    s33=rows[S33], s34=rows[S34])


_MEMORY: OrderedDict[str, MieTable] = OrderedDict()
_LOCK = threading.Lock()


def clear_memory_cache() -> None:
    """Forget the tables kept in memory (the disk cache stays)."""
    with _LOCK:
        _MEMORY.clear()


def _inputs(p: Particles) -> np.ndarray:
    return np.array([p.radius_um, p.n, p.k, p.number_per_m3], dtype="<f8")


def _key(p: Particles, host: np.ndarray) -> str:
    h = hashlib.sha256(TABLE_VERSION.encode() + b"\0")
    h.update(_inputs(p).tobytes())
    h.update(host.astype("<f8").tobytes())
    return h.hexdigest()


def cache_dir() -> Path:
    """The disk cache's directory: ``$LUMENLINK_OPTICS_CACHE``, else ``<numba cache dir>/optics``."""
    env = os.environ.get("LUMENLINK_OPTICS_CACHE")
    if env:
        return Path(env)
    import numba

    from tracer import numba_cache_dir
    return Path(numba.config.CACHE_DIR or numba_cache_dir()) / "optics"


def _digest(key: str, t: MieTable) -> str:
    h = hashlib.sha256(key.encode())
    for a in t:
        h.update(str(a.shape).encode())
        h.update(np.ascontiguousarray(a, dtype="<f8").tobytes())
    return h.hexdigest()


_SHAPES = {"sigma_ext": (GRID_N,), "sigma_sca": (GRID_N,), "g": (GRID_N,), "mu": (N_MU,), "cdf": (N_MIE, N_MU),
           "s12": (N_MIE, N_MU), "s33": (N_MIE, N_MU), "s34": (N_MIE, N_MU)}


def _load(path: Path, key: str, p: Particles, host: np.ndarray) -> MieTable | None:
    """The table in `path`, or None for a missing, unreadable, foreign or corrupt file."""
    try:
        with np.load(path, allow_pickle=False) as z:
            if str(z["version"]) != TABLE_VERSION or str(z["key"]) != key:
                return None
            if not (np.array_equal(z["inputs"], _inputs(p)) and np.array_equal(z["host_n"], host)):
                return None
            t = MieTable(**{f: z[f] for f in MieTable._fields})
            digest = str(z["digest"])
    except Exception:  # noqa: BLE001 - any unreadable file is simply rebuilt
        return None
    if any(a.dtype != np.dtype("<f8") or a.shape != _SHAPES[f] for f, a in zip(MieTable._fields, t, strict=True)):
        return None
    return t if digest == _digest(key, t) else None


def _save(path: Path, key: str, p: Particles, host: np.ndarray, t: MieTable) -> None:
    """Write atomically (temporary file + rename); give up silently where the directory is not writable."""
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=".mie.", suffix=".tmp", dir=path.parent)
        with os.fdopen(fd, "wb") as fh:
            np.savez(fh, version=np.array(TABLE_VERSION), key=np.array(key), inputs=_inputs(p), host_n=host,
                     digest=np.array(_digest(key, t)), **t._asdict())
        os.replace(tmp, path)
    except OSError:
        if tmp is not None:
            try:
                os.unlink(tmp)
            except OSError:
                pass


def mie_table(p: Particles, host_n: np.ndarray, where: str = "particles") -> MieTable:
    """The Mie table of particles `p` in a host of real index `host_n` ((GRID_N,) on the grid), from the memory
    cache, the disk cache or built. Raises `MaterialError` (naming the field) where x > `X_MAX` or
    σ_ext > `SIGMA_MAX` at some wavelength."""
    host = np.ascontiguousarray(host_n, dtype=np.float64)
    if host.shape != (GRID_N,) or not np.all(np.isfinite(host)) or not np.all(host > 0.0):
        raise ValueError(f"host_n must be ({GRID_N},) finite positive indices, got shape {host.shape}")
    _check_size(p, host, where)
    key = _key(p, host)
    with _LOCK:
        t = _MEMORY.get(key)
        if t is not None:
            _MEMORY.move_to_end(key)
            return t
    path = cache_dir() / f"mie-{key}.npz"
    t = _load(path, key, p, host)
    if t is None:
        t = _build(p, host, where)
        _save(path, key, p, host, t)
    for a in t:
        a.flags.writeable = False
    with _LOCK:
        _MEMORY[key] = t
        while len(_MEMORY) > MEMORY_ENTRIES:
            _MEMORY.popitem(last=False)
    return t


def packed(t: MieTable) -> np.ndarray:
    """(PACKED_ROWS, N_MU) float64: the rows the kernels read (layout in the module docstring)."""
    out = np.empty((PACKED_ROWS, N_MU))
    out[MU_ROW] = t.mu
    block = out[1:].reshape(N_MIE, ROWS_PER_NM, N_MU)
    block[:, CDF], block[:, S12], block[:, S33], block[:, S34] = t.cdf, t.s12, t.s33, t.s34
    return out


# ------------------------------------------------------------------------------------------- kernels


@njit(cache=True, error_model="numpy", _nrt=False)
def _sample_block(row0, lam):
    """First packed row of the sample nearest λ nm (clamped to 360 … 830)."""
    i = int((lam - LAMBDA_MIN) / MIE_STEP_NM + 0.5)
    return row0 + 1 + ROWS_PER_NM * min(max(i, 0), N_MIE - 1)


@njit(cache=True, error_model="numpy", _nrt=False)
def mie_sample_mu(tab, row0, lam, u):
    """cosθ of a Mie scattering at λ nm, drawn from the packed rows starting at `row0` (the nearest sample's
    phase function, uniform in μ between nodes); u uniform in [0, 1)."""
    r = _sample_block(row0, lam) + CDF
    k = max(find_in_cdf(tab[r], 0, N_MU, u), 1)
    c0, c1 = tab[r, k - 1], tab[r, k]
    t = (u - c0) / (c1 - c0) if c1 > c0 else 0.5
    t = min(max(t, 0.0), 1.0)
    m0, m1 = tab[row0 + MU_ROW, k - 1], tab[row0 + MU_ROW, k]
    return min(max(m0 + t * (m1 - m0), -1.0), 1.0)


@njit(cache=True, error_model="numpy", _nrt=False)
def mie_ratios(tab, row0, lam, mu):
    """(s12, s33, s34) = (S12, S33, S34)/S11 at cosθ = mu and λ nm (nearest sample, linear in μ)."""
    k = min(max(find_in_cdf(tab[row0 + MU_ROW], 0, N_MU, mu), 1), N_MU - 1)
    m0, m1 = tab[row0 + MU_ROW, k - 1], tab[row0 + MU_ROW, k]
    t = min(max((mu - m0) / (m1 - m0), 0.0), 1.0)
    b = _sample_block(row0, lam)
    s12 = tab[b + S12, k - 1] + t * (tab[b + S12, k] - tab[b + S12, k - 1])
    s33 = tab[b + S33, k - 1] + t * (tab[b + S33, k] - tab[b + S33, k - 1])
    s34 = tab[b + S34, k - 1] + t * (tab[b + S34, k] - tab[b + S34, k - 1])
    return s12, s33, s34
