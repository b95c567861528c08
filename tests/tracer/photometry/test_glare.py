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


# CIE 117-1995, Table 4.1 (the Luckiesh–Guth position index p by H/R across, T/R down; R the distance along the
# horizontal line of sight, T across it, H the height above the eye), rows T/R = 0, 0.5, 1.0, H/R = 0.0 … 1.7 in
# steps of 0.1; as transcribed in 123VincentB/eulumdat-ugr, src/eulumdat_ugr/guth.py (docs/LUMINANCE.md, References).
CIE117_TABLE_4_1 = {
    0.0: [1.00, 1.26, 1.53, 1.90, 2.35, 2.86, 3.50, 4.20, 5.00, 6.00, 7.00, 8.10, 9.25, 10.35, 11.70, 13.15, 14.70,
          16.20],
    0.5: [1.43, 1.60, 1.82, 2.10, 2.48, 2.91, 3.40, 3.98, 4.70, 5.50, 6.40, 7.30, 8.30, 9.40, 10.50, 11.75, 13.00,
          14.40],
    1.0: [2.11, 2.40, 2.75, 3.10, 3.50, 3.91, 4.40, 5.00, 5.60, 6.20, 7.00, 7.90, 8.80, 9.75, 10.80, 11.90, 12.95,
          14.00],
}


def test_guth_closed_form_reproduces_cie_117_table_4_1():
    """The closed form `guth_position_index` against the published table, for T/R ≤ 1 (the luminaires near the line
    of sight, which dominate a UGR): within 6.5 % in every cell (the closed form is a fit to the table; 6.5 % of p
    is 16 log₁₀ 1.065 = 0.44 UGR units for a single luminaire, under the half unit the published UGR tables round
    to), and exact at p(0, 0) = 1."""
    worst = 0.0
    for tr, row in CIE117_TABLE_4_1.items():
        for i, p_table in enumerate(row):
            hr = 0.1 * i
            beta = math.degrees(math.acos(1.0 / math.sqrt(1.0 + tr * tr + hr * hr)))
            alpha = math.degrees(math.atan2(tr, hr)) if (tr or hr) else 0.0
            worst = max(worst, abs(float(guth_position_index(alpha, beta)) / p_table - 1.0))
    assert worst <= 0.065, worst
    assert float(guth_position_index(0.0, 0.0)) == 1.0


def test_ugr_of_one_luminaire_with_the_tabulated_index():
    """One luminaire of L = 10 000 cd/m², ω = 0.01 sr at H/R = 0.5, T/R = 0 (p = 2.86 in Table 4.1) against
    L_b = 40 cd/m²: UGR = 8 log₁₀(0.25/40 × 10⁸ × 0.01 / 2.86²) = 23.07 by hand; with the closed-form p the rating
    moves by 16 log₁₀(p/2.86), under 0.05 here."""
    by_hand = 8 * math.log10(0.25 / 40 * 1e8 * 0.01 / 2.86 ** 2)
    assert by_hand == pytest.approx(23.07, abs=0.005)
    assert ugr([1e4], [0.01], [2.86], 40.0)["ugr"] == pytest.approx(by_hand, abs=1e-9)
    beta = math.degrees(math.atan(0.5))
    p = float(guth_position_index(0.0, beta))
    assert abs(ugr([1e4], [0.01], [p], 40.0)["ugr"] - by_hand) <= 0.05
