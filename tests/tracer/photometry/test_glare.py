"""Uniformity and UGR (tracer/photometry/glare.py) against hand-computed cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tracer.photometry.glare import guth_position_index, nine_points, pixel_geometry, ugr, ugr_from_image, uniformity


def test_uniformity_of_nine_values_by_hand():
    """Values 80 … 120: min/max 80/120, min/mean 80/100; with σ = 1 on each, σ(min/max) = u √(1/80² + 1/120²)."""
    v = np.array([100, 90, 110, 80, 120, 100, 95, 105, 100.0])
    u = uniformity(v, np.ones(9))
    assert u["min_max"] == pytest.approx(80 / 120) and u["min_mean"] == pytest.approx(0.8)
    assert u["min_max_stderr"] == pytest.approx(80 / 120 * math.sqrt(1 / 80 ** 2 + 1 / 120 ** 2))
    # min/mean: cov(min, mean) = σ²/9; σ(mean) = 1/3
    rel2 = 1 / 80 ** 2 + (1 / 3) ** 2 / 100 ** 2 - 2 * (1 / 9) / (80 * 100)
    assert u["min_mean_stderr"] == pytest.approx(0.8 * math.sqrt(rel2))
    assert uniformity(v)["min_max_stderr"] == 0.0


@pytest.mark.parametrize("bad", [[], [1.0, math.nan]])
def test_uniformity_refuses_empty_or_non_finite(bad):
    with pytest.raises(ValueError, match="finite value"):
        uniformity(bad)


def test_nine_points_lie_at_sixths():
    p = nine_points([0, 0, 0], [6, 0, 0], [0, 3, 0])
    assert p.shape == (9, 3)
    assert np.allclose(p[0], [1, 0.5, 0]) and np.allclose(p[4], [3, 1.5, 0]) and np.allclose(p[8], [5, 2.5, 0])


def test_guth_index_by_hand():
    """On the line of sight p = 1. At α = 30°, β = 20° (by hand): (35.2 − 9.5667 − 1.22 e^(−6.667)) × 0.02 =
    0.5126350, (21 + 8.0001 − 2.6667) × 0.004 = 0.1053336, p = e^0.6179686 = 1.822119 × 1.018131 = 1.855156."""
    assert guth_position_index(0.0, 0.0) == pytest.approx(1.0)
    assert guth_position_index(30.0, 20.0) == pytest.approx(1.855156, rel=2e-6)


def test_ugr_by_hand():
    """One luminaire of 10 000 cd/m² and 0.001 sr on the line of sight (p = 1), L_b = 20 cd/m²: 0.25/20 × 1e8 ×
    1e-3 = 1250, UGR = 8 log₁₀ 1250 = 24.775. Two such luminaires add 8 log₁₀ 2 = 2.408."""
    one = ugr([10_000.0], [0.001], [1.0], 20.0, stderr=[100.0])
    assert one["ugr"] == pytest.approx(24.7753, abs=1e-4)
    assert one["stderr"] == pytest.approx(8 / math.log(10) * 2 * 0.01)   # 2 σ_L/L in Σ, to first order
    two = ugr([10_000.0, 10_000.0], [0.001, 0.001], [1.0, 1.0], 20.0)
    assert two["ugr"] - one["ugr"] == pytest.approx(8 * math.log10(2))


@pytest.mark.parametrize("args, message", [
    (([1000.0], [0.01], [1.0], 0.0), "background"),
    (([0.0], [0.01], [1.0], 10.0), "no luminaire"),
])
def test_ugr_refuses_what_it_cannot_rate(args, message):
    with pytest.raises(ValueError, match=message):
        ugr(*args)


def test_ugr_from_image_sums_the_bright_pixels():
    """A uniform 50 cd/m² image with a 2 × 2 patch of 20 000 cd/m² just above its centre: the same UGR as the four
    pixels listed with their solid angles and position indices, against the background of 50."""
    w, h, fov = 40, 30, 60.0
    img = np.full((h, w), 50.0)
    img[12:14, 19:21] = 20_000.0
    got = ugr_from_image(img, fov)
    omega, beta, alpha = pixel_geometry(fov, w, h)
    sl = (slice(12, 14), slice(19, 21))
    want = ugr(img[sl].ravel(), omega[sl].ravel(), guth_position_index(alpha[sl], beta[sl]).ravel(), 50.0)
    assert got["source_pixels"] == 4 and got["background"] == pytest.approx(50.0)
    assert got["ugr"] == pytest.approx(want["ugr"])
