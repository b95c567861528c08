"""The half-luminance viewing angle of a conoscopic view (`tracer.sensors.luminance.half_angle`, issue 53's
viewing-angle spread).

- On exact views: a luminance falling as cosⁿθ reads the linear interpolation of its rings at half the axis value,
  within the interpolation's error of acos(2^(-1/n)); its standard error is what noisy views scatter by; a view that
  never falls to half reads its largest angle and says so; a view dark on its axis has none.
- Through the tracer: a Lambertian emitter of exitance M seen through a clear pane of n = 1.5 shows
  L(θ) = M/π T(θ), T the pane's transmission summed over its inner reflections. Paths from the eye carry no Stokes
  vector (the answer says so: polarization off for them), so each interface reflects the s/p average R̄ and
  T = (1 − R̄)/(1 + R̄), which falls to half its normal value at 79.4° (the polarized ½[(1 − Rs)/(1 + Rs) +
  (1 − Rp)/(1 + Rp)] at 79.9°, 2-4 % brighter from 60° on: what luminance through glass leaves out today). Each
  ring's reading and the half angle read from them agree with that form within 4 of their standard errors.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from tests.tracer.transport_scenes import box, quad, scene_of
from tracer.errors import SimulationError
from tracer.sensors.luminance import conoscope, half_angle, ring_means
from tracer.simulate import Simulation

THETA = np.linspace(0.0, 80.0, 17)
Z = 4.0


def cos_view(n: float, azimuths: int = 8, rel_err: float = 0.01) -> tuple[np.ndarray, np.ndarray]:
    lum = np.repeat((100.0 * np.cos(np.radians(THETA)) ** n)[:, None], azimuths, axis=1)
    return lum, rel_err * lum


@pytest.mark.parametrize("n", [2.0, 5.0, 20.0])
def test_a_cos_n_view_reads_where_its_rings_fall_to_half(n: float) -> None:
    lum, err = cos_view(n)
    deg, se, within = half_angle(THETA, lum, err)
    ring = lum[:, 0]
    interpolated = float(np.interp(0.5 * ring[0], ring[::-1], THETA[::-1]))   # ring values fall: read backwards
    exact = math.degrees(math.acos(2.0 ** (-1.0 / n)))                       # 45.0, 29.5, 15.1 degrees
    assert within and deg == pytest.approx(interpolated, abs=1e-9)
    assert abs(deg - exact) < 0.5, (deg, exact)   # the 5-degree rings' linear interpolation
    assert 0.0 < se < 1.0


def test_its_standard_error_is_what_noisy_views_scatter_by() -> None:
    """Views of cos⁵θ read by meters each with a 3 % standard error (ring 0 one meter, the others 8): the reported
    error is the scatter of the half angles of 4000 noisy views within 10 %, and their mean is unbiased to a tenth
    of it."""
    lum, err = cos_view(5.0, rel_err=0.03)
    deg, se, _ = half_angle(THETA, lum, err)
    rng = np.random.default_rng(5)
    noisy = lum + err * rng.standard_normal((4000, *lum.shape))
    noisy[:, 0, :] = noisy[:, 0, :1]   # the axis: one reading repeated
    got = np.array([half_angle(THETA, v, err)[0] for v in noisy])
    assert abs(got.std() / se - 1.0) < 0.1, (got.std(), se)
    assert abs(got.mean() - deg) < 0.1 * se + 0.05, (got.mean(), deg)


def test_a_view_that_stays_above_half_is_at_least_its_widest_angle_and_a_dark_one_has_none() -> None:
    flat = np.full((17, 8), 30.0)
    assert half_angle(THETA, flat, 0.01 * flat) == (80.0, 0.0, False)
    dark = flat.copy()
    dark[0] = 0.0
    deg, se, within = half_angle(THETA, dark, 0.01 * flat)
    assert math.isnan(deg) and math.isnan(se) and not within
    mean, mean_err = ring_means(flat, np.full((17, 8), 0.8))
    assert mean_err[0] == pytest.approx(0.8) and mean_err[1] == pytest.approx(0.8 / math.sqrt(8))


@pytest.mark.parametrize("theta, lum, words", [
    (THETA[:-1], np.ones((17, 8)), "theta_deg"),
    (THETA + 1.0, np.ones((17, 8)), "theta_deg"),
    (THETA[::-1], np.ones((17, 8)), "theta_deg"),
    (THETA, np.ones(17), "grids"),
    (THETA[:1], np.ones((1, 8)), "at least 2 rings"),
])
def test_a_view_that_is_not_one_is_refused_naming_the_field(theta, lum, words) -> None:
    with pytest.raises(SimulationError, match=words):
        half_angle(theta, lum, 0.1 * lum)


M_EXIT, N_PANE = 1500.0, 1.5


def pane_transmission(theta_deg: np.ndarray, polarized: bool = False) -> np.ndarray:
    """A clear pane's transmission at incidence θ in air, its inner reflections summed incoherently: with each
    interface's s/p average R̄, (1 − R̄)/(1 + R̄) (a path without a Stokes vector), or `polarized`, s and p apart."""
    ti = np.radians(theta_deg)
    tt = np.arcsin(np.sin(ti) / N_PANE)
    ci, ct = np.cos(ti), np.cos(tt)
    rs = ((ci - N_PANE * ct) / (ci + N_PANE * ct)) ** 2
    rp = ((N_PANE * ci - ct) / (N_PANE * ci + ct)) ** 2
    if polarized:
        return 0.5 * ((1 - rs) / (1 + rs) + (1 - rp) / (1 + rp))
    r = 0.5 * (rs + rp)
    return (1 - r) / (1 + r)


def half_root(polarized: bool) -> float:
    """Where `pane_transmission` falls to half its normal value, degrees."""
    normal = pane_transmission(np.zeros(1), polarized)[0]
    return math.degrees(brentq(lambda t: pane_transmission(np.degrees(t), polarized) / normal - 0.5, 0.1,
                               math.radians(89.0)))


def test_an_emitter_seen_through_a_pane_spreads_as_the_pane_s_averaged_transmission() -> None:
    """A 4 m square emitter (black behind) facing down at z = 2, a 6 m pane 5 cm thick 5-10 cm under it; the view
    of the emitter's centre from 5 m below (0 to 85 degrees in 5-degree rings; every line of sight crosses the pane
    and ends on the emitter, the 1-degree cones' footprints included)."""
    s, (emitter, pane) = scene_of(quad([-2.0, 2.0, 2.0], [4.0, 0.0, 0.0], [0.0, -4.0, 0.0]),
                                  box([-3.0, -3.0, 1.9], [3.0, 3.0, 1.95]))
    sim = Simulation(s, {emitter: {"type": "black"}, pane: {"type": "dielectric", "ior": N_PANE}},
                     [{"type": "area", "instances": [emitter], "exitance_lm_m2": M_EXIT}])
    views, res = conoscope(sim, [0.1, 0.0, 2.0], [0, 0, -1], theta_max_deg=85.0, rings=18, azimuths=6, distance=5.0,
                         max_photons=480_000, seed=12)
    mean, se = ring_means(views["luminance"], views["stderr"])
    exact = M_EXIT / math.pi * pane_transmission(views["theta_deg"])
    z = (mean - exact) / se
    assert np.all(se > 0) and np.all(np.abs(z) < Z), z
    deg, deg_err, within = half_angle(views["theta_deg"], views["luminance"], views["stderr"])
    ring_half = float(np.interp(0.5 * exact[0], exact[::-1], views["theta_deg"][::-1]))
    root = half_root(polarized=False)
    assert abs(root - 79.42) < 0.01 and abs(ring_half - root) < 0.3   # the rings' interpolation of the closed form
    assert abs(half_root(polarized=True) - 79.92) < 0.01
    assert res.effect_reasons["polarization"].startswith("off: paths from the eye"), res.effect_reasons
    assert within and 0.0 < deg_err < 2.0 and abs(deg - ring_half) < Z * deg_err, (deg, deg_err, ring_half)
