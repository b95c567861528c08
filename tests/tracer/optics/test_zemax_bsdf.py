"""Measured BSDF files in the Zemax / Radiant "BSDF Data Interchange" format (`tracer.optics.surfaces.zemax_bsdf`),
read into `measured_brdf` tables (issue 38).

Each test writes a file from a known analytic BRDF with the module's writer (values × an arbitrary scale, since the
format's values are relative and its TIS gives the level), reads it back through `measured_brdf`, and compares:
- a Lambertian file of ρ gives the table ρ/π in every cell (to rounding) and the Lambertian answer;
- a smooth lobe about the specular direction keeps its shape within the resampling's Taylor bound, and photons
  scattered by the table land in a region with the analytic lobe's probability, within 4 binomial σ plus that bound.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scatter_contract import Case

from tracer.optics.surfaces import measured_brdf, zemax_bsdf
from tracer.optics.surfaces.base import CONTINUES, MaterialError, spec_from_body

WHITE = ("white", 0.0, 0.0, 0.0, 0.0)
AOI = [0.0, 20.0, 40.0, 60.0, 80.0]
AZ = np.arange(0.0, 181.0, 10.0)
RADIAL = np.arange(0.0, 181.0, 3.0)


def lambertian(rho):
    return lambda ti, r, a: rho / math.pi * np.ones(np.broadcast(r, a).shape)


def lobe(ti, r, a):
    """0.1 (1 + cos r)² / π sr⁻¹: a broad lobe about the specular direction (r: degrees from it)."""
    return 0.1 * (1.0 + np.cos(np.radians(r))) ** 2 / math.pi * np.ones(np.broadcast(r, a).shape)


def table_of(text):
    return spec_from_body(measured_brdf.Spec, "measured_brdf", {"type": "measured_brdf", "table": text}, "test")


def test_a_lambertian_file_is_the_lambertian_table():
    text = zemax_bsdf.write(lambertian(0.6), [0, 30, 60], np.arange(0, 181, 15), np.arange(0, 181, 5), scale=16.0)
    assert zemax_bsdf.is_zemax(text)
    t = table_of(text).table
    assert t.shape == (3, 36, 36)
    np.testing.assert_allclose(t.values(), 0.6 / math.pi, rtol=1e-8)
    np.testing.assert_allclose(t.albedo(), 0.6, rtol=1e-8)


def test_a_smooth_lobe_keeps_its_shape_within_the_resampling_bound():
    t = table_of(zemax_bsdf.write(lobe, AOI, AZ, RADIAL, scale=3.0)).table
    mu = np.cos(np.radians(zemax_bsdf.THETA_O_EDGES))
    theta = np.degrees(np.arccos(np.sqrt((mu[:-1] ** 2 + mu[1:] ** 2) / 2)))   # the cells' centres
    dphi = (zemax_bsdf.DPHI_EDGES[:-1] + zemax_bsdf.DPHI_EDGES[1:]) / 2
    # Taylor: bilinear interpolation over a radial step h errs by ≤ h²/8 max|f''|, the cell mean against its centre
    # by ≤ d²/8 max|f''| over the cell's angular diagonal d (≤ √(2.5² + 5²)°); f'' of 0.1 (1 + cos r)²/π is at most
    # 0.4/π per rad² (at r = 0)
    h, d = math.radians(3.0), math.radians(math.hypot(2.5, 5.0))
    bound = (h * h + d * d) / 8 * 0.4 / math.pi
    for i, ti in enumerate(AOI):
        r, a = zemax_bsdf.specular_angles(ti, theta[:, None], dphi[None, :])
        exact = lobe(ti, r, a)
        scale = (exact * zemax_bsdf._cell_weights()).sum() / t.albedo()[i]   # the rows reflect their TIS
        assert np.max(np.abs(t.values()[i] * scale - exact)) <= bound, (ti, np.max(np.abs(t.values()[i] - exact)))


@pytest.mark.parametrize("theta", [20.0, 60.0])
def test_photons_scattered_by_the_table_follow_the_analytic_lobe(theta):
    s = table_of(zemax_bsdf.write(lobe, AOI, AZ, RADIAL, scale=3.0))
    n = 20_000
    t = math.radians(theta)
    out, _ = Case(measured_brdf, s, "front", theta, -np.array([math.sin(t), 0.0, math.cos(t)]), WHITE).run(n=n,
                                                                                                           seed=7)
    alive = out[:, 0] == CONTINUES
    wo = out[alive, 1:4]
    # the source lies towards +x (the photon arrives along −(sin θ, 0, cos θ)): the specular direction is (−sin, 0, cos)
    spec = np.array([-math.sin(t), 0.0, math.cos(t)])
    near = np.degrees(np.arccos(np.clip(wo @ spec, -1, 1))) < 30.0
    # the analytic probability of reflecting into the 30° cone about specular: ∫ f cosθ dω over it (fine midpoint)
    m = 600
    mu2 = (np.arange(m) + 0.5) / m
    th = np.degrees(np.arccos(np.sqrt(mu2)))
    ph = (np.arange(m) + 0.5) / m * 180.0
    r, a = zemax_bsdf.specular_angles(theta, th[:, None], ph[None, :])
    f = lobe(theta, r, a)
    p_near = float(np.mean(f * (r < 30.0)) * math.pi)
    p_all = float(np.mean(f) * math.pi)
    # the sampled row mixes the file's two neighbouring θi rows (linear in θi): exact where θ is a file angle
    got_all, got_near = alive.mean(), near.sum() / n
    assert abs(got_all - p_all) <= 4 * math.sqrt(p_all * (1 - p_all) / n) + 1e-6, (got_all, p_all)
    # the table's 2.5° × 5° cells blur the cone's rim: allow the projected share of the rim's cells
    rim = float(np.mean(f * (np.abs(r - 30.0) < 5.6)) * math.pi) / 2
    assert abs(got_near - p_near) <= 4 * math.sqrt(p_near * (1 - p_near) / n) + rim, (got_near, p_near, rim)


def _file(old: str = "", new: str = "") -> str:
    text = zemax_bsdf.write(lambertian(0.5), [0, 45], [0, 90, 180], [0, 45, 90])
    return text.replace(old, new) if old else text


@pytest.mark.parametrize("text, match", [
    (_file("ScatterType  BRDF", "ScatterType  BTDF"), "transmission"),
    (_file("SpectralContent  Monochrome", "SpectralContent  XYZ"), "tristimulus"),
    (_file("Symmetry  PlaneSymmetrical", "Symmetry  Asymmetrical"), "PlaneSymmetrical"),
    (_file("SampleRotation  1", "SampleRotation  2"), "anisotropic"),
    (_file("TIS 0.5", "TIS 1.5"), "TIS of angle of incidence"),
    (_file("DataEnd", ""), "DataEnd"),
    (_file("ScatterAzimuth  3", "ScatterAzimuth  4"), "expected"),
    (_file("0 90 180", "0 180 90"), "strictly increasing"),
    ("Source  Measured\nSymmetry  PlaneSymmetrical\n", "SpectralContent"),
])
def test_files_this_reader_does_not_take_are_refused_naming_why(text, match):
    with pytest.raises(MaterialError, match=match):
        table_of(text)


def test_negative_values_and_zero_data_are_refused():
    text = _file()
    lines = text.splitlines()
    k = next(i for i, line in enumerate(lines) if line.startswith("TIS")) + 1
    neg = "\n".join(lines[:k] + ["-1 " + lines[k].split(" ", 1)[1]] + lines[k + 1:])
    with pytest.raises(MaterialError, match="≥ 0"):
        table_of(neg)
    zero = zemax_bsdf.write(lambda ti, r, a: np.zeros(np.broadcast(r, a).shape), [0], [0, 180], [0, 90])
    zero = zero.replace("TIS 0\n", "TIS 0.5\n")
    with pytest.raises(MaterialError, match="are 0 over the hemisphere"):
        table_of(zero)
