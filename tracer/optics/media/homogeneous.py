"""``homogeneous``: Beer–Lambert absorption and Henyey–Greenstein scattering, the same everywhere inside.

| field (on the dielectric) | type | unit | range | default |
| --- | --- | --- | --- | --- |
| absorption_per_m | float | 1/m | [0, 1e9] | 0 |
| scattering_per_m | float | 1/m | [0, 1e9] | 0 |
| g | float | — | (−1, 1) | 0 |

Parameter row: (σa, σs, g, 0). The single-scattering albedo is σs/(σa+σs). The Henyey–Greenstein
sampler inverts the CDF in a form that stays finite for g → ±1 and for |g| → 0 (switching to the
isotropic case below |g| < 1e-4), and the phase function value is computed without cancellation at
cosθ → ±1. Effects: `absorption` where σa > 0, `scattering` where σs > 0.
"""

from __future__ import annotations

import math

from numba import njit

from tracer.optics.frames import onb

_G_ISOTROPIC = 1e-4


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
def coefficients(M, mi):
    return M.mpar[mi, 0], M.mpar[mi, 1]


@njit(cache=True, error_model="numpy", _nrt=False)
def scatter(M, mi, dx, dy, dz, u1, u2):
    return hg_scatter(dx, dy, dz, M.mpar[mi, 2], u1, u2)
