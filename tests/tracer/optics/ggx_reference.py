"""GGX microfacet BSDFs evaluated in numpy, written from the papers (not from the kernels), for the tests of
`microfacet` and `rough_dielectric`: the density of the directions a photon leaves along, per steradian, with the
probability of leaving at all folded in (what an analog sampler must produce).

Local frame: z along the shading normal, x along the roughness αx (a brushing axis), y = z × x.

- D(m) = 1 / (π αx αy m_z⁴ (1 + (m_x²/αx² + m_y²/αy²) / m_z²)²)           (Walter et al. 2007 eq. 33; Heitz 2014)
- Λ(w) = (−1 + √(1 + (αx² w_x² + αy² w_y²) / w_z²)) / 2,  G2 = 1 / (1 + Λ(wi) + Λ(wo))   (height-correlated)
- reflection:   p(wo) = f_r |cos θo| = F(wi·h) D(h) G2 / (4 cos θi),  h = (wi + wo)/|wi + wo|      (Walter eq. 20)
- transmission: p(wo) = f_t |cos θo| = |wi·h| |wo·h| n2² (1 − F(wi·h)) D(h) G2 / (cos θi (n1 wi·h + n2 wo·h)²),
  h = −(n1 wi + n2 wo) turned to +z, only where wi·h > 0 > wo·h                                  (Walter eq. 21)
"""

from __future__ import annotations

import numpy as np


def fresnel(c, n1, n2):
    """Unpolarized Fresnel reflectance (Rs + Rp)/2 at cos θi = c (array), 1 under total internal reflection."""
    c = np.clip(c, 0.0, 1.0)
    s2 = (n1 / n2) ** 2 * (1.0 - c * c)
    ct = np.sqrt(np.clip(1.0 - s2, 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        rs = (n1 * c - n2 * ct) / (n1 * c + n2 * ct)
        rp = (n2 * c - n1 * ct) / (n2 * c + n1 * ct)
    return np.where(s2 >= 1.0, 1.0, 0.5 * (rs * rs + rp * rp))


def ggx_d(m, ax, ay):
    z = m[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        a = m[..., 0] ** 2 / ax ** 2 + m[..., 1] ** 2 / ay ** 2 + z * z
        return np.where(z > 0, 1.0 / (np.pi * ax * ay * a * a), 0.0)


def ggx_lambda(w, ax, ay):
    z2 = np.maximum(w[..., 2] ** 2, 1e-300)
    return 0.5 * (-1.0 + np.sqrt(1.0 + (ax * ax * w[..., 0] ** 2 + ay * ay * w[..., 1] ** 2) / z2))


def density(wi, wo, ax, ay, n1=None, n2=None, reflectance=None):
    """(reflected, transmitted) density per sr of leaving along wo (..., 3) for a photon arriving from wi (3,),
    cos θi > 0. A conductor-like facet of constant `reflectance` (n1, n2 None) reflects only; a dielectric facet
    (n1 where the photon is, n2 beyond) reflects with Fresnel's F and refracts with 1 − F."""
    wi = np.asarray(wi, float)
    ci = wi[2]
    up = wo[..., 2] > 0
    g2 = 1.0 / (1.0 + ggx_lambda(wi, ax, ay) + ggx_lambda(wo, ax, ay))
    h = wo + wi
    h = h / np.linalg.norm(h, axis=-1, keepdims=True)
    c = np.sum(h * wi, axis=-1)
    f = reflectance if n1 is None else fresnel(c, n1, n2)
    p_r = np.where(up, f * ggx_d(h, ax, ay) * g2 / (4.0 * ci), 0.0)
    if n1 is None:
        return p_r, np.zeros_like(p_r)
    ht = -(n1 * wi + n2 * wo)
    ht = ht * np.where(ht[..., 2:3] < 0, -1.0, 1.0)
    ht = ht / np.linalg.norm(ht, axis=-1, keepdims=True)
    a, b = np.sum(ht * wi, axis=-1), np.sum(ht * wo, axis=-1)
    ok = ~up & (a > 0) & (b < 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        p_t = np.abs(a * b) * n2 * n2 * (1.0 - fresnel(a, n1, n2)) * ggx_d(ht, ax, ay) * g2 / (
            ci * (n1 * a + n2 * b) ** 2)
    return p_r, np.where(ok, p_t, 0.0)


def sphere_grid(n_cos: int, n_phi: int, lo: float = -1.0, hi: float = 1.0):
    """Midpoints (n_cos, n_phi, 3) of an equal-area grid in (cos θ, φ) over cos θ ∈ [lo, hi], and the cell's solid
    angle (dω = dcosθ dφ)."""
    c = lo + (np.arange(n_cos) + 0.5) * (hi - lo) / n_cos
    p = (np.arange(n_phi) + 0.5) * 2 * np.pi / n_phi
    c, p = np.meshgrid(c, p, indexing="ij")
    s = np.sqrt(1.0 - c * c)
    return np.stack([s * np.cos(p), s * np.sin(p), c], -1), (hi - lo) / n_cos * 2 * np.pi / n_phi


def albedo(wi, ax, ay, n_theta=1000, n_phi=1000, **facet):
    """(R, T): the reflected and transmitted fractions, ∫ p dω by the midpoint rule in (θ, φ) over each hemisphere
    (dω = sin θ dθ dφ; fine near the poles, where the lobes of normal incidence peak)."""
    th = (np.arange(n_theta) + 0.5) * (np.pi / 2) / n_theta
    ph = (np.arange(n_phi) + 0.5) * 2 * np.pi / n_phi
    t, p = np.meshgrid(th, ph, indexing="ij")
    dw = np.sin(t) * (np.pi / 2 / n_theta) * (2 * np.pi / n_phi)
    out = []
    for sign, k in ((1.0, 0), (-1.0, 1)):
        wo = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), sign * np.cos(t)], -1)
        out.append(float(np.sum(density(wi, wo, ax, ay, **facet)[k] * dw)))
    return tuple(out)
