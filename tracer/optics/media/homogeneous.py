"""``homogeneous``: Beer–Lambert absorption, Henyey–Greenstein or Mie scattering and fluorescence, the same
everywhere inside a solid.

Body (a dielectric's ``medium``: ``{"type": "homogeneous", ...}``):

| field | type | unit | range | default |
| --- | --- | --- | --- | --- |
| absorption_per_m | float or table over λ | 1/m | [0, 1e9] | 0 |
| scattering_per_m | float | 1/m | [0, 1e9] | 0 |
| g | float | — | (−1, 1) | 0 |
| fluorescence | absorption and re-emission (`tracer.optics.media.fluorescence`) | — | — | none |
| particles | spheres (`tracer.optics.mie`): Mie scattering instead of Henyey–Greenstein | — | — | none |

Parameter row: (σa, σs, g, σf, quantum yield, emission line; `fluorescence`; the first row of the Mie table,
`MIE_ROW`), σa may vary with λ (``mtab[0]``). The single-scattering albedo is σs/(σa+σs). The Henyey–Greenstein
sampler inverts the CDF in a form that stays finite for g → ±1 and for |g| → 0 (switching to the
isotropic case below |g| < 1e-4), and the phase function value is computed without cancellation at
cosθ → ±1. The particles' Mie table depends on the index of the solid holding them (the host's, passed to
`mie`, `row`, `tables` and `phase`). Effects: `absorption` where σa > 0, `scattering` where σs > 0,
`fluorescence`, `mie` with particles, and `spectral` with either of these or an absorption table.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tracer.jit import njit
from tracer.optics.frames import onb
from tracer.optics.media.fluorescence import EMISSION_NM, QY, SIGMA_F, Fluorescence, parse_fluorescence, reemit
from tracer.optics.mie import MieTable, Particles, mie_ratios, mie_sample_mu, mie_table, packed, parse_particles
from tracer.optics.polarization import ON, S1, S2, E, across, apply_interface, depolarize, rotate_into, set_frame
from tracer.optics.spectra import GRID_N, grid_or_value, scalar, varies
from tracer.optics.surfaces.base import MIE_ROW, N_MPAR, MaterialError, bounds, mparam, optional
from tracer.rng import uniform

NAME = "homogeneous"
_G_ISOTROPIC = 1e-4


@dataclass(frozen=True)
class Spec:
    """Absorption, scattering (Henyey–Greenstein, or Mie by particles), fluorescence: the same everywhere inside."""

    absorption_per_m: Any = field(default=0.0, metadata=bounds(0.0, 1e9, value="spectral", mcolumn=0,
                                                               doc="absorption coefficient σa, 1/m (or a table)"))
    scattering_per_m: float = field(default=0.0, metadata=bounds(0.0, 1e9, doc="scattering coefficient σs, 1/m"))
    g: float = field(default=0.0, metadata=bounds(-1.0, 1.0, lo_open=True, hi_open=True,
                                                  doc="Henyey–Greenstein asymmetry g, dimensionless "
                                                      "(−1 backward, 0 isotropic, 1 forward)"))
    fluorescence: Fluorescence | None = field(default=None, metadata=optional(
        parse_fluorescence, "absorption and isotropic re-emission inside"))
    particles: Particles | None = field(default=None, metadata=optional(
        parse_particles, "spheres suspended inside: Mie scattering and absorption at each wavelength"))

    def check(self) -> str | None:
        if self.particles is not None and self.scattering_per_m > 0:
            return ("give either 'scattering_per_m' (Henyey–Greenstein) or 'particles' (Mie), not both: the "
                    "particles scatter with their own phase function")
        return None


def host_check(spec: Spec, host_ior) -> str | None:
    """What is wrong with this medium inside a solid of index `host_ior`: its particles' Mie table, built (or found
    in the cache) now, so that its limits are the body's and the query then finds it ready."""
    if spec.particles is None:
        return None
    try:
        mie(spec, host_ior)
    except MaterialError as exc:
        return str(exc)
    return None


def mie(spec: Spec, host_ior) -> MieTable:
    """The Mie table of the particles in a host of index `host_ior` (`tracer.optics.mie`, cached by content)."""
    if spec.particles is None:
        raise MaterialError("a medium without particles has no Mie table")
    return mie_table(spec.particles, np.broadcast_to(grid_or_value(host_ior), (GRID_N,)), "particles")


def clear(spec: Spec) -> bool:
    """Whether nothing inside absorbs, scatters or fluoresces (the kernels then skip the medium)."""
    return (not varies(spec.absorption_per_m) and scalar(spec.absorption_per_m) == 0 and spec.scattering_per_m == 0
            and spec.fluorescence is None and spec.particles is None)


def row(spec: Spec, host_ior) -> np.ndarray:
    """(N_MPAR,) the medium row at a white photon: σa, σs, g, σf, quantum yield, emission line (`MIE_ROW` left to
    the packer)."""
    m = np.zeros(N_MPAR)
    m[:3] = scalar(spec.absorption_per_m), spec.scattering_per_m, spec.g
    fl = spec.fluorescence
    if fl is not None:
        m[SIGMA_F], m[QY], m[EMISSION_NM] = scalar(fl.absorption_per_m), fl.quantum_yield, fl.emission.mono_nm
    if spec.particles is not None:
        t = mie(spec, host_ior)
        m[0] += float(np.mean(t.sigma_ext - t.sigma_sca))
        m[1] = float(np.mean(t.sigma_sca))
    return m


def tables(spec: Spec, host_ior) -> dict[int, np.ndarray]:
    """The tables only this kind knows how to build, by medium row column: the particles' σa (with the medium's
    own) and σs over λ; the fluorescence's σf over λ and its emission spectrum's cdf."""
    fl = spec.fluorescence
    out = {}
    if spec.particles is not None:
        t = mie(spec, host_ior)
        out[0] = grid_or_value(spec.absorption_per_m) + (t.sigma_ext - t.sigma_sca) + np.zeros(GRID_N)
        out[1] = np.array(t.sigma_sca)
    if fl is not None and varies(fl.absorption_per_m):
        out[SIGMA_F] = fl.absorption_per_m.grid()
    if fl is not None and fl.emission.mono_nm == 0:
        out[EMISSION_NM] = fl.emission_cdf()
    return out


def phase(spec: Spec, host_ior) -> np.ndarray | None:
    """The particles' packed Mie table (`tracer.optics.mie.packed`), None without particles."""
    return None if spec.particles is None else packed(mie(spec, host_ior))


def polarizing(spec: Spec) -> tuple[int, float]:
    """Particles scatter with a Mie Mueller matrix (`tracer.effects`): two interactions of diattenuation up to 1."""
    return (2, 1.0) if spec.particles is not None else (0, 0.0)


def effects(spec: Spec) -> tuple[str, ...]:
    out = []
    if varies(spec.absorption_per_m) or spec.absorption_per_m > 0:
        out.append("absorption")
    if spec.scattering_per_m > 0:
        out.append("scattering")
    if spec.fluorescence is not None:
        out.append("fluorescence")
    if spec.particles is not None:
        out.append("mie")
    if set(out) & {"fluorescence", "mie"} or varies(spec.absorption_per_m):
        out.append("spectral")
    return tuple(out)


@njit(cache=True)
def hg_phase(g, cos_theta):
    """Henyey–Greenstein phase function p(cosθ) per steradian (integrates to 1 over the sphere)."""
    d = 1.0 + g * g - 2.0 * g * cos_theta
    d = max(d, 1e-300)
    return (1.0 - g * g) / (4.0 * math.pi * d * math.sqrt(d))


@njit(cache=True)
def hg_sample_cos(g, u):
    """cosθ of a Henyey–Greenstein scattering, u uniform in [0, 1); result clamped to [−1, 1]."""
    if abs(g) < _G_ISOTROPIC:
        return 1.0 - 2.0 * u
    s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u)
    c = (1.0 + g * g - s * s) / (2.0 * g)
    return min(1.0, max(-1.0, c))


@njit(cache=True)
def hg_scatter(dx, dy, dz, g, u1, u2):
    """New unit direction after a Henyey–Greenstein scattering of unit direction d."""
    c = hg_sample_cos(g, u1)
    s = math.sqrt(max(0.0, 1.0 - c * c))
    phi = 2.0 * math.pi * u2
    t, b = onb(dx, dy, dz)
    x = s * math.cos(phi)
    y = s * math.sin(phi)
    nx = x * t[0] + y * b[0] + c * dx
    ny = x * t[1] + y * b[1] + c * dy
    nz = x * t[2] + y * b[2] + c * dz
    inv = 1.0 / math.sqrt(nx * nx + ny * ny + nz * nz)
    return nx * inv, ny * inv, nz * inv


@njit(cache=True)
def transmittance(sigma, t):
    """exp(−σ t), exact 1 for σ = 0 (also for t = ∞, where σ·t would be NaN)."""
    if sigma <= 0.0:
        return 1.0
    return math.exp(-sigma * t)


@njit(cache=True)
def sample_free_flight(sigma, u):
    """Distance to the next event with density σ exp(−σ t); ∞ for σ = 0. u uniform in [0, 1)."""
    if sigma <= 0.0:
        return math.inf
    return -math.log1p(-u) / sigma


@njit(cache=True, error_model="numpy", _nrt=False)
def coefficients(M, mi, lam):
    """(σa, σs, σf) in 1/m at λ nm (σf, fluorescent absorption, only for a photon with a wavelength)."""
    sig_f = mparam(M, mi, SIGMA_F, lam) if lam > 0.0 else 0.0
    return mparam(M, mi, 0, lam), mparam(M, mi, 1, lam), sig_f


@njit(cache=True, error_model="numpy", _nrt=False)
def event(M, mi, dx, dy, dz, lam, sig_s, sig_f, key, dim, pol):
    """A scattering or fluorescence event: (alive, dx, dy, dz, λ, power factor, dim); the choice between
    them is drawn only where σf > 0, so that scenes without fluorescence trace the same paths. Both leave the
    photon unpolarized (Henyey–Greenstein has no Mueller matrix; re-emission forgets the absorbed state), except a
    Mie scattering, which acts with the particles' Mueller matrix (`mie_scatter`)."""
    if sig_f > 0.0:
        u = uniform(key, dim)
        dim += 1
        if u * (sig_s + sig_f) >= sig_s:
            alive, lam2, f = reemit(M, mi, lam, uniform(key, dim), uniform(key, dim + 1))
            dx, dy, dz = hg_scatter(dx, dy, dz, 0.0, uniform(key, dim + 2), uniform(key, dim + 3))
            depolarize(pol)
            return alive, dx, dy, dz, lam2, f, dim + 4
    row0 = M.mpar[mi, MIE_ROW]
    if row0 >= 0.0:
        dx, dy, dz, dim = mie_scatter(M.phase, int(row0), dx, dy, dz, lam, key, dim, pol)
        return True, dx, dy, dz, lam, 1.0, dim
    dx, dy, dz = hg_scatter(dx, dy, dz, M.mpar[mi, 2], uniform(key, dim), uniform(key, dim + 1))
    depolarize(pol)
    return True, dx, dy, dz, lam, 1.0, dim + 2


MAX_AZIMUTH_TRIES = 64   # rejection draws of a polarized Mie azimuth (each accepted with probability ≥ ½... on average
                         # exactly ½: the chance of running out is 2⁻⁶⁴)


@njit(cache=True, error_model="numpy", _nrt=False)
def mie_scatter(tab, row0, dx, dy, dz, lam, key, dim, pol):
    """A Mie scattering at λ nm from the packed table at `row0` (`tracer.optics.mie`): (dx, dy, dz, dim).

    cos θ is drawn from S11 (the phase function, exact for any incident state: the polarized terms vanish over
    the azimuth). An unpolarized photon takes a uniform azimuth φ. A polarized one draws φ from its own
    conditional density ∝ 1 + s12(θ) (s1 cos 2φ + s2 sin 2φ), by rejection (analog: the weight is unchanged),
    and leaves with the normalised image of its state under the scattering matrix, in the frame whose x axis
    is the scattering plane's normal."""
    mu = mie_sample_mu(tab, row0, lam, uniform(key, dim))
    dim += 1
    sin_t = math.sqrt(max(0.0, 1.0 - mu * mu))
    polarized = pol[ON] != 0.0
    if polarized:   # the photon's frame axis, taken across d (a depolarizing event may have left it stale)
        ok, ex, ey, ez = across(dx, dy, dz, pol[E], pol[E + 1], pol[E + 2])
        if not ok:
            t, _ = onb(dx, dy, dz)
            ex, ey, ez = t[0], t[1], t[2]
        yx, yy, yz = dy * ez - dz * ey, dz * ex - dx * ez, dx * ey - dy * ex
        s12, s33, s34 = mie_ratios(tab, row0, lam, mu)
        phi = 0.0
        for _ in range(MAX_AZIMUTH_TRIES):
            phi = 2.0 * math.pi * uniform(key, dim)
            accept = 0.5 * (1.0 + s12 * (pol[S1] * math.cos(2.0 * phi) + pol[S2] * math.sin(2.0 * phi)))
            dim += 2
            if uniform(key, dim - 1) < accept:
                break
    else:
        t, b = onb(dx, dy, dz)
        ex, ey, ez, yx, yy, yz = t[0], t[1], t[2], b[0], b[1], b[2]
        phi = 2.0 * math.pi * uniform(key, dim)
        dim += 1
    c, s = math.cos(phi), math.sin(phi)
    ux, uy, uz = c * ex + s * yx, c * ey + s * yy, c * ez + s * yz     # in the scattering plane, across d
    nx, ny, nz = mu * dx + sin_t * ux, mu * dy + sin_t * uy, mu * dz + sin_t * uz
    inv = 1.0 / math.sqrt(nx * nx + ny * ny + nz * nz)
    nx, ny, nz = nx * inv, ny * inv, nz * inv
    if polarized:   # frame x = the scattering plane's normal, across both directions
        px, py, pz = c * yx - s * ex, c * yy - s * ey, c * yz - s * ez
        rotate_into(pol, dx, dy, dz, px, py, pz)
        apply_interface(pol, 1.0 - s12, 1.0 + s12, s33, s34)
        set_frame(pol, nx, ny, nz, px, py, pz)
    return nx, ny, nz, dim
