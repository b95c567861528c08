"""Optics and estimation building blocks without a scene: Fresnel, refraction, Henyey–Greenstein, sampling,
the counter-based RNG, batch means, effect sets, body validation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from emission import emit

from tracer.effects import EffectError, derive_effects, photon_state, with_forced
from tracer.optics.frames import sample_cosine
from tracer.optics.lights import LightError, pack_lights, spot_solid_angle
from tracer.optics.media.homogeneous import hg_phase, hg_sample_cos, hg_scatter, sample_free_flight, transmittance
from tracer.optics.surfaces.base import MaterialError, reflect
from tracer.optics.surfaces.dielectric import fresnel_dielectric, refract
from tracer.optics.surfaces.dispatch import material_row, pack_materials
from tracer.rng import uniforms
from tracer.transport.estimate import Estimate


def test_fresnel_normal_incidence_and_symmetry():
    for n in (1.33, 1.5, 2.4):
        r0 = ((n - 1) / (n + 1)) ** 2
        assert fresnel_dielectric(1.0, 1.0, n) == pytest.approx(r0, rel=1e-12)
        assert fresnel_dielectric(1.0, n, 1.0) == pytest.approx(r0, rel=1e-12)
        # the slab's incoherent transmission 2n/(n²+1) follows from it
        assert (1 - r0) / (1 + r0) == pytest.approx(2 * n / (n * n + 1), rel=1e-12)


def test_fresnel_grazing_tir_and_index_matched():
    assert fresnel_dielectric(0.0, 1.0, 1.5) == pytest.approx(1.0)
    crit = math.asin(1 / 1.5)
    assert fresnel_dielectric(math.cos(crit + 1e-9), 1.5, 1.0) == 1.0     # beyond the critical angle
    below = fresnel_dielectric(math.cos(crit - 1e-6), 1.5, 1.0)
    assert 0.9 < below < 1.0                                              # continuous up to it
    for c in np.linspace(0, 1, 11):
        assert fresnel_dielectric(c, 1.5, 1.5) == 0.0                     # n1 = n2: exactly no reflection
    for c in np.linspace(0, 1, 101):                                      # always a probability, never NaN
        for n1, n2 in ((1.0, 1.5), (1.5, 1.0), (1.0, 1.0 + 1e-12)):
            r = fresnel_dielectric(c, n1, n2)
            assert 0.0 <= r <= 1.0


def test_refraction_obeys_snell_and_reflect_is_an_involution():
    rng = np.random.default_rng(1)
    for _ in range(200):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        n = np.array([0.0, 0.0, 1.0])
        if d @ n > 0:
            d = -d
        eta = rng.uniform(0.5, 2.0)
        ok, tx, ty, tz = refract(*d, *n, eta)
        sin_i = math.sqrt(max(0, 1 - (d @ n) ** 2))
        if eta * sin_i >= 1:
            assert not ok
            continue
        t = np.array([tx, ty, tz])
        assert ok and np.linalg.norm(t) == pytest.approx(1.0)
        assert math.sqrt(max(0, 1 - (t @ n) ** 2)) == pytest.approx(eta * sin_i, abs=1e-12)
        assert t @ n < 0                                                  # it goes through
        r = np.array(reflect(*d, *n))
        np.testing.assert_allclose(np.array(reflect(*r, *n)), d, atol=1e-14)
    ok, *t = refract(0.3, 0.0, -math.sqrt(1 - 0.09), 0.0, 0.0, 1.0, 1.0)
    np.testing.assert_allclose(t, [0.3, 0.0, -math.sqrt(1 - 0.09)], atol=1e-15)


@pytest.mark.parametrize("g", [0.0, 1e-6, 0.5, -0.7, 0.999, -0.999, 0.999999, -0.999999])
def test_henyey_greenstein_mean_cosine_is_g_and_stays_finite(g):
    u = (np.arange(200_000) + 0.5) / 200_000          # stratified: the mean is accurate to ~1e-9
    c = np.array([hg_sample_cos(g, x) for x in u])
    assert np.all(np.isfinite(c)) and np.all(np.abs(c) <= 1.0)
    assert c.mean() == pytest.approx(g, abs=2e-4)
    for x in (0.0, 1.0 - 2 ** -53):
        assert -1.0 <= hg_sample_cos(g, x) <= 1.0
    # the phase function integrates to 1 over the sphere (Gauss–Legendre in cosθ; peaked for |g| → 1)
    if abs(g) < 0.99:
        x, w = np.polynomial.legendre.leggauss(400)
        total = sum(wi * hg_phase(g, xi) for xi, wi in zip(x, w, strict=True))
        assert 2 * math.pi * total == pytest.approx(1.0, rel=1e-6)
    d = hg_scatter(0.0, 0.0, 1.0, g, 0.3, 0.6)
    assert np.linalg.norm(d) == pytest.approx(1.0)


def test_free_flight_and_transmittance_at_extreme_optical_depths():
    assert transmittance(0.0, math.inf) == 1.0
    assert transmittance(1e-6, 1.0) == pytest.approx(1 - 1e-6, rel=1e-12)
    assert transmittance(1e3, 1.0) == pytest.approx(math.exp(-1e3), abs=0.0)
    assert transmittance(1e5, 1.0) == 0.0
    assert sample_free_flight(0.0, 0.5) == math.inf
    u = (np.arange(100_000) + 0.5) / 100_000
    for sigma in (1e-6, 1.0, 1e3):
        t = np.array([sample_free_flight(sigma, x) for x in u])
        assert t.mean() == pytest.approx(1 / sigma, rel=1e-3)


def test_cosine_sampling_has_mean_cosine_two_thirds():
    rng = np.random.default_rng(3)
    n = np.array([0.3, -0.5, 0.8])
    n /= np.linalg.norm(n)
    c = np.array([np.dot(sample_cosine(*n, *rng.random(2)), n) for _ in range(20000)])
    assert np.all(c >= 0)
    assert c.mean() == pytest.approx(2 / 3, abs=0.01)


def test_rng_is_a_pure_function_of_its_counters():
    a = uniforms(7, 3, 11, 64)
    np.testing.assert_array_equal(a, uniforms(7, 3, 11, 64))
    assert not np.array_equal(a, uniforms(7, 3, 12, 64))
    assert not np.array_equal(a, uniforms(7, 4, 11, 64))
    assert not np.array_equal(a, uniforms(8, 3, 11, 64))
    u = np.concatenate([uniforms(1, b, p, 8) for b in range(20) for p in range(200)])
    assert np.all((u >= 0) & (u < 1))
    assert u.mean() == pytest.approx(0.5, abs=0.01)
    assert u.var() == pytest.approx(1 / 12, abs=0.005)
    with pytest.raises(ValueError, match=">= 0"):
        uniforms(-1, 0, 0, 1)


def test_estimate_batch_means_and_merge():
    rng = np.random.default_rng(5)
    x = rng.normal(10.0, 2.0, size=(400, 3))
    e = Estimate.empty(3)
    e.add(x[:150])
    f = Estimate.empty(3)
    f.add(x[150:])
    m = e.merge(f)
    np.testing.assert_allclose(m.mean, x.mean(axis=0), rtol=1e-12)
    np.testing.assert_allclose(m.stderr, x.std(axis=0, ddof=1) / 20, rtol=1e-9)
    assert Estimate.empty(2).relative_error().tolist() == [math.inf, math.inf]
    z = Estimate.empty(1)
    z.add(np.zeros((4, 1)))
    assert z.relative_error()[0] == 0.0
    with pytest.raises(ValueError, match="expected 3 bins"):
        e.add(np.zeros((1, 2)))
    with pytest.raises(ValueError, match="not finite"):
        e.add(np.array([[1.0, np.nan, 0.0]]))


def test_effect_sets_follow_the_materials():
    def eff(*bodies):
        return derive_effects(bodies)

    assert eff({"type": "lambertian", "reflectance": 0.5}, {"type": "black"}) == ["lambertian"]
    assert eff({"type": "mirror", "reflectance": 0.9}) == ["lambertian", "specular"]
    assert eff({"type": "mix", "diffuse": 0.5, "specular": 0.0}) == ["lambertian"]
    # a solid has two Fresnel interfaces in a row: polarization by physics (issue 38), not in a clear n = 1 volume
    assert eff({"type": "dielectric", "ior": 1.5}) == ["lambertian", "fresnel", "polarization"]
    assert eff({"type": "dielectric", "ior": 1.5, "absorption_per_m": 1.0, "scattering_per_m": 2.0}) == \
        ["lambertian", "fresnel", "absorption", "scattering", "polarization"]
    assert eff({"type": "dielectric", "ior": 1.0, "scattering_per_m": 2.0}) == ["lambertian", "fresnel", "scattering"]
    assert with_forced(["lambertian"], ("scattering",)) == ["lambertian", "scattering"]
    assert eff({"type": "diffuser", "transmittance": 0.5}) == ["lambertian"]
    assert photon_state(["lambertian", "fresnel", "absorption", "scattering"]) == "white"
    assert photon_state(["lambertian", "polarization"]) == "polarized"
    assert photon_state(with_forced(["lambertian", "polarization"], ("coating",))) == "polarized-spectral"
    assert eff({"type": "polarizer", "axis": [1, 0, 0]}) == ["lambertian", "polarization"]
    light = {"type": "point", "position": [0, 0, 0], "flux_lm": 1.0, "polarization": {"type": "circular",
                                                                                     "handedness": "left"}}
    assert derive_effects([{"type": "black"}], [light]) == ["lambertian", "polarization"]
    assert derive_effects([{"type": "black"}], [{**light, "polarization": None}]) == ["lambertian"]
    with pytest.raises(EffectError, match="unknown effect"):
        with_forced(["lambertian"], ("birefringence",))


@pytest.mark.parametrize(("body", "match"), [
    ({"type": "velvet"}, "unknown material type 'velvet'"),
    ({"type": "lambertian"}, "missing field"),
    ({"type": "lambertian", "reflectance": 1.2}, "must be in \\[0, 1\\]"),
    ({"type": "lambertian", "reflectance": 0.5, "colour": 1}, "unknown field"),
    ({"type": "mix", "diffuse": 0.7, "specular": 0.5}, "at most 1"),
    ({"type": "dielectric", "ior": 0.0}, "'ior' must be in \\(0, 10\\]"),
    ({"type": "dielectric", "ior": 1.5, "g": 1.0}, "'g' must be in \\(-1, 1\\)"),
    ({"type": "dielectric", "ior": 1.5, "absorption_per_m": float("nan")}, "finite number"),
    ("black", "expected a material body"),
])
def test_bad_material_bodies_are_rejected(body, match):
    with pytest.raises(MaterialError, match=match):
        material_row(body)


def test_materials_must_cover_the_instances():
    with pytest.raises(MaterialError, match="instance 1 has no material"):
        pack_materials({0: {"type": "black"}}, None, [0, 1], set())
    with pytest.raises(MaterialError, match="instance id 5 is not in the scene"):
        pack_materials({5: {"type": "black"}}, None, [0], set())


@pytest.mark.parametrize(("body", "match"), [
    ({"type": "laser"}, "unknown light type"),
    ({"type": "point", "position": [0, 0, 1]}, "exactly one of"),
    ({"type": "point", "position": [0, 0, 1], "intensity_cd": 1, "flux_lm": 2}, "exactly one of"),
    ({"type": "point", "position": [0, 0], "intensity_cd": 1}, "3 finite numbers"),
    ({"type": "point", "position": [0, 0, 1], "intensity_cd": -1}, "must be >= 0"),
    ({"type": "point", "position": [0, 0, 1], "intensity_cd": 1, "colour": 2}, "unknown field"),
    ({"type": "spot", "position": [0, 0, 1], "direction": [0, 0, 0], "cone_deg": 30, "intensity_cd": 1},
     "zero vector"),
    ({"type": "spot", "position": [0, 0, 1], "direction": [0, 0, -1], "cone_deg": 30, "falloff_deg": 40,
      "intensity_cd": 1}, "must not exceed"),
    ({"type": "collimated", "origin": [0, 0, 1], "direction": [0, 0, -1], "illuminance_lx": 5},
     "or 'width' and 'height'"),
    ({"type": "collimated", "origin": [0, 0, 1], "direction": [0, 0, -1], "radius": 0, "illuminance_lx": 5},
     "'radius' must be >"),
    ({"type": "goniometric", "position": [0, 0, 1], "format": "ies", "data": "junk"}, "no 'TILT=' line"),
    ({"type": "goniometric", "position": [0, 0, 1], "format": "xml", "data": "junk"}, "'format' must be"),
    ({"type": "area", "instances": [], "exitance_lm_m2": 5}, "non-empty list"),
    ({"type": "point", "position": [0, 0, 1], "intensity_cd": 0}, "total flux is zero"),
])
def test_bad_light_bodies_are_rejected(body, match):
    with pytest.raises(LightError, match=match):
        pack_lights([body])


def test_spot_flux_and_emission_weights_are_unbiased():
    body = {"type": "spot", "position": [0, 0, 0], "direction": [0, 0, -1], "cone_deg": 40, "falloff_deg": 15,
            "intensity_cd": 100.0}
    lights = pack_lights([body])
    ci, co = math.cos(math.radians(25)), math.cos(math.radians(40))
    assert lights.flux_total[0] == pytest.approx(100.0 * spot_solid_angle(co, ci))
    # brute force: ∫ I dΩ over the sphere
    x, w = np.polynomial.legendre.leggauss(2000)
    prof = np.clip((x - co) / (ci - co), 0, 1)
    prof = prof * prof * (3 - 2 * prof)
    assert lights.flux_total[0] == pytest.approx(2 * math.pi * 100.0 * float((w * prof).sum()), rel=1e-6)
    f = emit(lights, n=40_000, seed=2)[:, 6]
    assert f.mean() == pytest.approx(1.0, abs=4 * f.std() / 200 + 1e-12)
    assert pack_lights([dict(body, intensity_cd=None, flux_lm=500.0)]).flux_total[0] == pytest.approx(500.0)


def test_goniometric_emission_reproduces_the_table(tmp_path):
    from pathlib import Path
    text = (Path(__file__).resolve().parents[2] / "fixtures" / "photometry" / "rab_bayled78_4.ies").read_text()
    lights = pack_lights([{"type": "goniometric", "position": [0, 0, 3], "format": "ies", "data": text}])
    assert lights.flux_total[0] == pytest.approx(5820.155, rel=1e-5)
    samples = emit(lights, n=60_000, seed=4)
    f = samples[:, 6]
    assert f.mean() == pytest.approx(1.0, abs=4 * f.std() / math.sqrt(len(f)))
    # flux into the cone γ < 30° (downward, -z) against the table's exact integral
    d = samples[:, 3:6]
    inside = -d[:, 2] > math.cos(math.radians(30))
    est = lights.flux_total[0] * (f * inside).mean()
    from tracer.photometry.files import parse_photometry
    p = parse_photometry("ies", text)
    cells = p.cell_flux()
    g_hi = p.gamma_deg[1:]
    ref = cells[:, g_hi <= 30.0 + 1e-9].sum()
    sd = lights.flux_total[0] * (f * inside).std() / math.sqrt(len(f))
    assert abs(est - ref) < 4 * sd
