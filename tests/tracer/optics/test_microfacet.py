"""The `microfacet` kind (GGX, issue 38) against closed forms, through the switch the transport kernel inlines
(`scatter_contract.Case`: a flat quad, front side +z, node frame = world, N photons each on its own stream).

- White furnace: a facet reflectance of 1 keeps, on average, the single-scattering albedo
  E(μi) = ∫ D(h) G2(wi, wo) / (4 cosθi) dωo (F = 1), integrated here by the midpoint rule over the outgoing
  hemisphere (400 × 800 cells; 1600 × 1600 moves it by < 1e-5): 0.947666 (α = 0.2), 0.687851 (α = 0.5), 0.698253
  (α = 0.5, 60°), 0.306854 (α = 1), each within 4σ; what it loses (1 − E) is what facets would send on in a second
  bounce, which this model leaves out (stated in the kind's docstring).
- Smooth limit: α = 1e-4 leaves along the mirror direction (median 2α, 99 % within 2α√99 = 2e-3) with the
  metal's Fresnel reflectance (Rs + Rp)/2 of n − ik at 45°, as `mirror` does.
- Lobe width, brushed: at normal incidence the visible normals are D(m) cosθm, whose scaled slopes
  (tanθm cosφ/αx, tanθm sinφ/αy) have the radial cdf u = r²/(1 + r²) and a uniform azimuth; with αx = 0.02,
  αy = 0.08 along and across the axis, u's first 9 tenths (tanθm < 3α, where shadowing is below 1e-3 of σ; the
  steep tail goes into the surface) and the azimuth there are uniform within 4 binomial σ of all photons, and the
  spread of the outgoing directions along x over along y (interquartile ranges) is αx/αy within 5 %.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scatter_contract import Case, mean_and_error

from tracer.optics.surfaces import microfacet
from tracer.optics.surfaces.base import CONTINUES, MaterialError, spec_from_body

WHITE = ("white", 0.0, 0.0, 0.0, 0.0)
K = 4.0


def spec(**body):
    return spec_from_body(microfacet.Spec, "microfacet", {"type": "microfacet", **body}, "test")


def arriving(theta_deg: float) -> np.ndarray:
    t = math.radians(theta_deg)
    return -np.array([math.sin(t), 0.0, math.cos(t)])


def single_scatter_albedo(alpha: float, theta_i: float, nt: int = 400, nph: int = 800) -> float:
    """∫ D(h) G2 / (4 cosθi cosθo) cosθo dωo for the isotropic GGX, F = 1, by the midpoint rule."""
    wi = np.array([math.sin(theta_i), 0.0, math.cos(theta_i)])
    th = (np.arange(nt) + 0.5) * (math.pi / 2) / nt
    ph = (np.arange(nph) + 0.5) * 2 * math.pi / nph
    t, p = np.meshgrid(th, ph, indexing="ij")
    wo = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1)
    h = wo + wi
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    a2 = alpha * alpha
    d = 1.0 / (math.pi * a2 * h[..., 2] ** 4 * (1 + (h[..., 0] ** 2 + h[..., 1] ** 2) / h[..., 2] ** 2 / a2) ** 2)

    def lam(t2):
        return 0.5 * (-1.0 + np.sqrt(1.0 + a2 * t2))

    g2 = 1.0 / (1.0 + lam(math.tan(theta_i) ** 2) + lam(np.tan(t) ** 2))
    f = d * g2 / (4.0 * math.cos(theta_i) * np.cos(t))
    return float(np.sum(f * np.cos(t) * np.sin(t)) * (math.pi / 2 / nt) * (2 * math.pi / nph))


@pytest.mark.parametrize(("alpha", "theta", "expected"), [(0.2, 0.0, 0.947666), (0.5, 0.0, 0.687851),
                                                          (0.5, 60.0, 0.698253), (1.0, 0.0, 0.306854)])
def test_white_furnace_keeps_the_single_scattering_albedo(alpha, theta, expected):
    assert single_scatter_albedo(alpha, math.radians(theta)) == pytest.approx(expected, abs=2e-6)
    case = Case(microfacet, spec(alpha=alpha, reflectance=1.0), "front", theta, arriving(theta), WHITE)
    out, _ = case.run(n=20_000, seed=3)
    mean, err = mean_and_error(np.where(out[:, 0] == CONTINUES, out[:, 4], 0.0))
    assert abs(mean - expected) <= K * err, (mean, err, expected)
    alive = out[:, 0] == CONTINUES
    assert np.all(out[alive, 3] > 0)          # every survivor leaves on the arrival side


def test_the_smooth_limit_is_the_mirror():
    n, k = 0.96, 6.69
    case = Case(microfacet, spec(alpha=1e-4, metal=[n, k]), "front", 45.0, arriving(45.0), WHITE)
    out, _ = case.run(n=20_000, seed=4)
    alive = out[:, 0] == CONTINUES
    d = arriving(45.0)
    mirror = d - 2 * d[2] * np.array([0.0, 0.0, 1.0])
    # GGX's tail: the angle to the mirror direction, about 2 tanθm, exceeds x with probability α² / (α² + x²/4):
    # its 99th percentile is 2α√99 = 2.0e-3 at α = 1e-4, and it shrinks with α
    dev = np.linalg.norm(out[alive, 1:4] - mirror, axis=1)
    assert np.median(dev) < 3e-4 and np.percentile(dev, 99) < 3e-3
    eps = complex(n, -k) ** 2
    c = math.cos(math.radians(45.0))
    w = np.sqrt(eps - (1 - c * c))
    r = 0.5 * (abs((c - w) / (c + w)) ** 2 + abs((eps * c - w) / (eps * c + w)) ** 2)
    mean, err = mean_and_error(np.where(alive, out[:, 4], 0.0))
    assert abs(mean - r) <= K * max(err, math.sqrt(r * (1 - r) / len(out))), (mean, err, r)


def test_a_brushed_lobe_has_the_ggx_width_along_and_across_its_axis():
    ax, ay = 0.02, 0.08
    case = Case(microfacet, spec(alpha=ax, alpha_y=ay, axis=[1.0, 0.0, 0.0], reflectance=1.0), "front", 0.0,
                arriving(0.0), WHITE)
    n = 20_000
    out, _ = case.run(n=n, seed=5)
    alive = out[:, 0] == CONTINUES
    wo = out[alive, 1:4]
    h = wo + np.array([0.0, 0.0, 1.0])
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    sx, sy = h[:, 0] / h[:, 2] / ax, h[:, 1] / h[:, 2] / ay
    r2 = sx * sx + sy * sy
    u = r2 / (1 + r2)
    # facets steeper than 45° (GGX's long tail: u > 0.99) send the photon into the surface, and shadowing takes a
    # little more there: only u < 0.9 (tanθm < 3α, loss below 1e-3 of a bin's σ) is compared, each bin a binomial
    # share of all n photons
    counts = np.histogram(u, bins=10, range=(0.0, 1.0))[0][:9]
    sigma = math.sqrt(n * 0.1 * 0.9)
    assert np.all(np.abs(counts - 0.1 * n) <= K * sigma), counts
    assert 0.9 * n - counts.sum() <= (~alive).sum() + (u >= 0.9).sum()
    az = np.histogram((np.arctan2(sy, sx)[u < 0.9] / (2 * math.pi)) % 1.0, bins=8, range=(0.0, 1.0))[0]
    p = 0.9 / 8
    assert np.all(np.abs(az - p * n) <= K * math.sqrt(n * p * (1 - p))), az
    assert 0.99 < alive.mean() < 1.0
    iq = np.subtract(*np.percentile(wo[:, 0], [75, 25])) / np.subtract(*np.percentile(wo[:, 1], [75, 25]))
    assert iq == pytest.approx(ax / ay, rel=0.05)


@pytest.mark.parametrize(("body", "field"), [
    ({"alpha": 0.0, "reflectance": 1.0}, "'alpha'"), ({"alpha": 1.5, "reflectance": 1.0}, "'alpha'"),
    ({"alpha": 0.1, "alpha_y": -1, "reflectance": 1.0}, "'alpha_y'"),
    ({"alpha": 0.1, "axis": [0, 0, 0], "reflectance": 1.0}, "'axis'"),
    ({"alpha": 0.1, "metal": [0.9], "reflectance": 1.0}, "'metal'"),
    ({"alpha": 0.1, "metal": [0.96, 6.69], "reflectance": 0.5}, "exactly one of 'reflectance' and 'metal'"),
    ({"alpha": 0.1}, "exactly one of 'reflectance' and 'metal'"), ({"reflectance": 1.0}, "'alpha'"),
    ({"alpha": 0.1, "reflectance": 1.0, "roughness": 2}, "'roughness'")])
def test_bad_bodies_name_their_field(body, field):
    with pytest.raises(MaterialError) as info:
        spec(**body)
    assert field in str(info.value)


def test_through_the_transport_kernel_a_rough_white_plane_reflects_its_single_scattering_albedo():
    """A 100 lx beam straight down onto a rough plane (α = 0.5, facet reflectance 1); a 100 m receiver disk 1 m up,
    facing down, takes all the reflected flux but the 1e-4 sr within 0.6° of the horizon: E = 0.687851."""
    from tracer.scene import Scene
    from tracer.simulate import Simulation
    from tracer.warmup import box

    s = Scene()
    plane = s.add_instance(s.add_geometry(*box([-500, -500, -0.1], [500, 500, 0.0])), np.eye(4))
    s.commit()
    beam = 0.01
    sim = Simulation(s, {plane: {"type": "microfacet", "alpha": 0.5, "reflectance": 1.0}},
                     [{"type": "collimated", "origin": [0, 0, 2.0], "direction": [0, 0, -1], "radius": beam,
                       "illuminance_lx": 100.0}])
    assert sim.effects == ["lambertian", "specular"]
    res = sim.illuminance([[0, 0, 1.0]], [[0, 0, -1.0]], radius=100.0, max_photons=40_000, seed=2)
    to_fraction = 100.0 ** 2 / (100.0 * beam ** 2)
    f, e = res.lux[0] * to_fraction, res.stderr[0] * to_fraction
    assert abs(f - 0.687851) <= K * e, (f, e)
