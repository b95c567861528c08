"""Mie tables (tracer.optics.mie): efficiencies and matrix elements against Wiscombe's MIEV0 and Bohren &
Huffman's BHMIE, the sampled phase function against g, the Rayleigh limit, the disk cache and the body's
validation.

Reference values: Wiscombe, "Mie scattering calculations", NCAR/TN-140 (1979), and B&H, "Absorption and
Scattering of Light by Small Particles" (1983), Appendix A (m = 1.55, x = 2π·0.525/0.6328; the BHMIE table
is printed to 6 significant digits).
"""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest

from tracer.optics import mie
from tracer.optics.spectra import GRID_N
from tracer.optics.surfaces.base import MaterialError

LAM = 500.0                          # nm: a `MIE_NM` sample, the wavelength the single-x tables are built for
I_LAM = int((LAM - 360.0) / 5.0)     # its sample index
G_LAM = int(LAM - 360.0)             # its grid index
X_BH = 2.0 * math.pi * 0.525 / 0.6328   # B&H's x = 5.21282 (the rounded 5.2128 moves Q_ext by 4e-5)


@pytest.fixture(autouse=True)
def _cache(tmp_path, monkeypatch):
    """Every test starts with an empty memory cache and its own disk cache."""
    monkeypatch.setenv("LUMENLINK_OPTICS_CACHE", str(tmp_path / "optics"))
    mie.clear_memory_cache()
    yield
    mie.clear_memory_cache()


def particles_for(m: complex, x: float, number: float = 1e12) -> mie.Particles:
    """Spheres of index m (n − ik) whose size parameter is x at 500 nm in vacuum (host index 1)."""
    return mie.Particles(x * LAM * 1e-3 / (2.0 * math.pi), m.real, 0.0 - m.imag, number)


VACUUM = np.ones(GRID_N)
# (m = n − ik, x, Q_ext, Q_sca, g, tolerance): Wiscombe's MIEV0 and B&H's BHMIE values, the tolerance half a unit
# of their last printed digit (miepython truncates the series at Wiscombe's N, good to ~1e-6 relative).
CASES = [
    (1.55 + 0j, X_BH, 3.10543, 3.10543, 0.63314, 5e-6),
    (1.5 - 1j, 1.0, 2.336321, 0.6634538, 0.192136, 5e-7),
    (1.33 - 1e-5j, 100.0, 2.101321, 2.096594, 0.868959, 5e-7),
]


@pytest.mark.parametrize(("m", "x", "qext", "qsca", "g", "tol"), CASES)
def test_efficiencies_match_wiscombe(m, x, qext, qsca, g, tol):
    got = mie.efficiencies(m, x)
    assert got == pytest.approx((qext, qsca, g), abs=tol)


def test_table_coefficients_are_n_c_on_the_grid():
    """σ = N Q π r² at a sample wavelength (same code path: only units can differ, so 1e-12), and the linear
    interpolation between samples 5 nm apart stays within 1e-4 of the exact value (x ≈ 7.6: Q varies by a few
    percent over 5 nm, its curvature term is ~1e-5)."""
    p = mie.Particles(0.5, 1.59, 0.0, 1e15)
    t = mie.mie_table(p, np.full(GRID_N, 1.33))
    area = math.pi * 0.5e-6**2
    for lam, tol in ((550, 1e-12), (552, 1e-4)):
        x = 2.0 * math.pi * 0.5 * 1.33 / (lam * 1e-3)
        qext, qsca, g = mie.efficiencies(1.59 / 1.33, x)
        assert t.sigma_sca[lam - 360] == pytest.approx(1e15 * qsca * area, rel=tol)
        assert t.sigma_ext[lam - 360] == pytest.approx(1e15 * qext * area, rel=tol)
        assert t.g[lam - 360] == pytest.approx(g, abs=tol)
    assert t.sigma_ext.shape == t.sigma_sca.shape == t.g.shape == (GRID_N,)


def test_amplitudes_follow_bohren_huffman():
    """S11 (normalised forward), POL = −S12/S11, S33/S11 and S34/S11 at 0°, 9°, …, 180° match B&H's BHMIE table
    to 2e-6 (6 printed digits, single precision); miepython's S1_S2 are their complex conjugates."""
    s11_bh = [1.0, 0.785390, 0.356897, 0.0766119, 0.0355355, 0.0701845, 0.0574313, 0.0219660, 0.0125959, 0.0173750,
              0.0124601, 0.00679093, 0.00954239, 0.00863419, 0.00227421, 0.00543998, 0.0160243, 0.0188852, 0.0195254,
              0.0301676, 0.0383189]
    pol_bh = [0.0, -0.00459811, -0.0458541, -0.364744, -0.534997, 0.00959953, 0.0477927, -0.440604, -0.831996,
              0.0341670, 0.230462, -0.713472, -0.756255, -0.281215, -0.239612, -0.850804, -0.706334, -0.891081,
              -0.783319, -0.196194, 0.0]
    s33_bh = [1.0, 0.999400, 0.986022, 0.843603, 0.686967, 0.959825, 0.985371, 0.648043, 0.203255, 0.795354,
              0.937497, -0.00717397, -0.0394748, 0.536251, 0.967602, 0.187531, 0.495254, 0.453277, -0.391613,
              -0.962069, -1.0]
    s34_bh = [0.0, 0.0343261, 0.160184, 0.394076, -0.491787, -0.280434, 0.163584, 0.621216, -0.516208, -0.605182,
              0.260742, 0.700647, -0.653085, -0.795835, 0.0795798, -0.490882, -0.505781, -0.0226817, 0.482752,
              0.189556, 0.0]
    mu = np.cos(np.radians(9.0 * np.arange(21)))
    s1, s2 = mie.amplitudes(1.55, X_BH, mu)
    s11, s12, s33, s34 = mie.mueller_ratios(s1, s2)
    np.testing.assert_allclose(s11 / s11[0], s11_bh, rtol=5e-6)
    np.testing.assert_allclose(-s12, pol_bh, atol=2e-6)
    np.testing.assert_allclose(s33, s33_bh, atol=2e-6)
    np.testing.assert_allclose(s34, s34_bh, atol=2e-6)
    import miepython
    w1, w2 = miepython.S1_S2(1.55, X_BH, mu, norm="wiscombe")
    np.testing.assert_allclose(s1, np.conj(w1), rtol=1e-10)
    np.testing.assert_allclose(s2, np.conj(w2), rtol=1e-10)


def test_table_ratios_follow_bohren_huffman():
    """Through the packed table and the kernel: the B&H values at 90° (exact: μ = 0 is a node) and, at the other
    angles, within the linear interpolation's error between nodes ≤ 4.1e-3 rad apart (h²/8·|f''| with f varying on
    the scale 1/x: ≲ 1e-3). A sphere's matrix is non-depolarizing: s12² + s33² + s34² = 1 at every node."""
    t = mie.mie_table(particles_for(1.55, X_BH), VACUUM)
    tab = mie.packed(t)
    s12, s33, s34 = mie.mie_ratios(tab, 0, LAM, 0.0)
    assert (-s12, s33, s34) == pytest.approx((0.230462, 0.937497, 0.260742), abs=2e-6)
    s12, s33, s34 = mie.mie_ratios(tab, 0, LAM, math.cos(math.radians(63.0)))
    assert (-s12, s33, s34) == pytest.approx((-0.440604, 0.648043, 0.621216), abs=1e-3)
    np.testing.assert_allclose(t.s12**2 + t.s33**2 + t.s34**2, 1.0, atol=1e-12)


def table_mean_mu(t: mie.MieTable, i: int) -> float:
    """The exact mean μ of the kernel's distribution for sample i: uniform in μ inside each node interval."""
    return float(np.sum(np.diff(t.cdf[i]) * 0.5 * (t.mu[1:] + t.mu[:-1])))


@pytest.mark.parametrize(("m", "x"), [(c[0], c[1]) for c in CASES])
def test_sampled_mean_mu_is_g(m, x, rng):
    """Mean of 200k draws of `mie_sample_mu` = g within 4 standard errors (σ_μ/√n ≈ 1e-3). The table's own mean
    (no noise) is within 2e-4 of g: the node spacing biases it by ~h²·x (measured ≤ 5e-5 here), five times
    inside the 1e-3 the transport needs."""
    t = mie.mie_table(particles_for(m, x), VACUUM)
    g = mie.efficiencies(m, x)[2]
    assert t.g[G_LAM] == pytest.approx(g, abs=1e-15)
    assert table_mean_mu(t, I_LAM) == pytest.approx(g, abs=2e-4)
    tab = mie.packed(t)
    draws = np.fromiter((mie.mie_sample_mu(tab, 0, LAM, u) for u in rng.random(200_000)), float, 200_000)
    assert np.all((draws >= -1.0) & (draws <= 1.0))
    assert abs(draws.mean() - g) < 4.0 * draws.std() / math.sqrt(draws.size)


@pytest.mark.parametrize(("m", "x"), [(1.33, 1000.0), (1.33, 1e4)])
def test_large_spheres_mean_mu_is_g(m, x, monkeypatch):
    """Large spheres: the ripple of S11 is far finer than the nodes, and trapezoids on the nodes alone miss g by
    1.6e-3 (x = 1000) and 2.5e-3 (x = 1e4); the sub-samples (≤ 2/x rad apart) bring the table's mean within 2e-4
    (measured 4e-5). One sample's table through the builder's own path (a full table at x = 1e4 takes ~10 s)."""
    a, b = mie._coefficients(m, x)
    g = mie._efficiencies_ab(a, b, x)[2]

    def mean_mu() -> float:
        cdf = mie._angular(a, b, x)[0]
        return float(np.sum(np.diff(cdf) * 0.5 * (mie.MU[1:] + mie.MU[:-1])))

    assert mean_mu() == pytest.approx(g, abs=2e-4)
    monkeypatch.setattr(mie, "SUB_DTHETA_X", 1e9)                 # the nodes alone
    assert abs(mean_mu() - g) > 1e-3


def test_rayleigh_limit():
    """x = 0.01, m = 1.5: light scattered at 90° is fully polarized, s12(0) = −1 (the |S2|²/|S1|² left is
    O(x⁴) ≈ 1e-10, so 1e-6 holds); the phase function is ∝ 1 + μ², s12 = −(1 − μ²)/(1 + μ²), s33 = 2μ/(1 + μ²),
    s34 = 0, up to the magnetic-dipole and quadrupole terms, O(x²(m² + 2)/30) ≈ 1.4e-5: tolerance 1e-4."""
    t = mie.mie_table(particles_for(1.5, 0.01), VACUUM)
    s12, s33, s34 = mie.mie_ratios(mie.packed(t), 0, LAM, 0.0)
    assert s12 == pytest.approx(-1.0, abs=1e-6)
    mu = t.mu
    np.testing.assert_allclose(t.cdf[I_LAM], 3.0 / 8.0 * (mu + mu**3 / 3.0 + 4.0 / 3.0), atol=1e-4)
    np.testing.assert_allclose(t.s12[I_LAM], -(1 - mu**2) / (1 + mu**2), atol=1e-4)
    np.testing.assert_allclose(t.s33[I_LAM], 2 * mu / (1 + mu**2), atol=1e-4)
    np.testing.assert_allclose(t.s34[I_LAM], 0.0, atol=1e-4)


def test_cdf_is_monotone_and_packed_layout():
    t = mie.mie_table(mie.Particles(5.0, 1.5, 0.01, 1e12), np.full(GRID_N, 1.33))
    assert t.cdf.shape == t.s12.shape == (mie.N_MIE, mie.N_MU)
    assert np.all(np.diff(t.cdf, axis=1) >= 0.0)
    assert np.all(t.cdf[:, 0] == 0.0) and np.all(t.cdf[:, -1] == 1.0)
    assert t.mu[0] == -1.0 and t.mu[-1] == 1.0 and np.all(np.diff(t.mu) > 0.0)
    tab = mie.packed(t)
    assert tab.shape == (mie.PACKED_ROWS, mie.N_MU) and tab.dtype == np.float64
    np.testing.assert_array_equal(tab[mie.MU_ROW], t.mu)
    i = 7
    base = 1 + mie.ROWS_PER_NM * i
    for off, rows in ((mie.CDF, t.cdf), (mie.S12, t.s12), (mie.S33, t.s33), (mie.S34, t.s34)):
        np.testing.assert_array_equal(tab[base + off], rows[i])
    # the kernels read the nearest sample: 397.4 nm → 395 nm (i = 7), 397.6 nm → 400 nm; λ is clamped to the grid
    mu0 = 0.3
    k = np.searchsorted(t.mu, mu0)
    w = (mu0 - t.mu[k - 1]) / (t.mu[k] - t.mu[k - 1])
    for lam, j in ((397.4, 7), (397.6, 8), (100.0, 0), (2000.0, mie.N_MIE - 1)):
        assert mie.mie_ratios(tab, 0, lam, mu0)[0] == pytest.approx((1 - w) * t.s12[j, k - 1] + w * t.s12[j, k],
                                                                    abs=1e-15)
    # a table packed after other rows is read from its own first row
    stacked = np.vstack([np.zeros((3, mie.N_MU)), tab])
    assert mie.mie_sample_mu(stacked, 3, 500.0, 0.42) == mie.mie_sample_mu(tab, 0, 500.0, 0.42)


def test_index_matched_spheres_do_not_scatter():
    """m = 1: σ is rounding noise (< 1e-20 1/m where the same spheres in air give ~1e3), and a table whose S11
    vanishes everywhere is isotropic and unpolarizing."""
    t = mie.mie_table(mie.Particles(1.0, 1.33, 0.0, 1e12), np.full(GRID_N, 1.33))
    assert np.all(np.abs(t.sigma_ext) < 1e-20) and np.all(np.abs(t.sigma_sca) < 1e-20)
    zeros = np.zeros(10, np.complex128)
    cdf, s12, s33, s34 = mie._angular(zeros, zeros, 5.0)
    np.testing.assert_allclose(cdf, 0.5 * (mie.MU + 1.0), atol=1e-15)
    assert np.all(s12 == 0.0) and np.all(s33 == 1.0) and np.all(s34 == 0.0)


def test_disk_cache_loads_without_miepython(tmp_path, monkeypatch):
    p = mie.Particles(0.5, 1.59, 0.0, 1e15)
    host = np.full(GRID_N, 1.33)
    first = mie.mie_table(p, host)
    files = list((tmp_path / "optics").glob("mie-*.npz"))
    assert len(files) == 1
    assert mie.mie_table(p, host) is first                        # memory cache
    mie.clear_memory_cache()
    monkeypatch.setitem(sys.modules, "miepython", None)           # any import of it now fails
    second = mie.mie_table(p, host)
    for a, b in zip(first, second, strict=True):
        np.testing.assert_array_equal(a, b)
    with pytest.raises(ImportError):                               # the guard works: a build would fail
        mie.mie_table(mie.Particles(0.6, 1.59, 0.0, 1e15), host)


@pytest.mark.parametrize("damage", ["garbage", "truncated", "foreign"])
def test_disk_cache_rebuilds_a_bad_file(tmp_path, monkeypatch, damage):
    p = mie.Particles(0.5, 1.59, 0.0, 1e15)
    host = np.full(GRID_N, 1.33)
    good = mie.mie_table(p, host)
    (path,) = (tmp_path / "optics").glob("mie-*.npz")
    if damage == "garbage":
        path.write_bytes(b"not a table")
    elif damage == "truncated":
        path.write_bytes(path.read_bytes()[:5000])
    else:                                                          # another table's file under this name
        mie.mie_table(mie.Particles(0.6, 1.59, 0.0, 1e15), host)
        other = next(f for f in (tmp_path / "optics").glob("mie-*.npz") if f != path)
        other.replace(path)
    mie.clear_memory_cache()
    builds = []
    build = mie._build
    monkeypatch.setattr(mie, "_build", lambda *a: builds.append(1) or build(*a))
    again = mie.mie_table(p, host)
    assert builds == [1]
    np.testing.assert_array_equal(again.cdf, good.cdf)
    mie.clear_memory_cache()
    mie.mie_table(p, host)                                         # the rebuilt file is whole again
    assert builds == [1]


def test_unwritable_cache_is_skipped(tmp_path, monkeypatch):
    (tmp_path / "file").write_text("")
    monkeypatch.setenv("LUMENLINK_OPTICS_CACHE", str(tmp_path / "file" / "optics"))   # cannot be a directory
    t = mie.mie_table(mie.Particles(0.5, 1.59, 0.0, 1e15), np.full(GRID_N, 1.33))
    assert t.sigma_sca.max() > 0.0


GOOD = {"radius_um": 0.5, "ior": [1.59, 0.0], "number_per_m3": 1e15}


def test_parse_good_body():
    assert mie.parse_particles(GOOD, "particles", "m1") == mie.Particles(0.5, 1.59, 0.0, 1e15)
    assert mie.parse_particles({"radius_um": 1000, "ior": (10, 10), "number_per_m3": 1e30}, "particles", "m1") == \
        mie.Particles(1000.0, 10.0, 10.0, 1e30)


BAD = [
    ("not a dict", "particles"),
    ({"radius_um": 0.5, "ior": [1.59, 0.0]}, "number_per_m3"),
    ({**GOOD, "colour": 1}, "colour"),
    ({**GOOD, "radius_um": True}, "radius_um"),
    ({**GOOD, "radius_um": "0.5"}, "radius_um"),
    ({**GOOD, "radius_um": 0}, "radius_um"),
    ({**GOOD, "radius_um": -1.0}, "radius_um"),
    ({**GOOD, "radius_um": 1000.5}, "radius_um"),
    ({**GOOD, "radius_um": float("nan")}, "radius_um"),
    ({**GOOD, "radius_um": float("inf")}, "radius_um"),
    ({**GOOD, "ior": 1.59}, "ior"),
    ({**GOOD, "ior": [1.59]}, "ior"),
    ({**GOOD, "ior": [1.59, 0.0, 0.0]}, "ior"),
    ({**GOOD, "ior": [True, 0.0]}, "ior[0]"),
    ({**GOOD, "ior": ["1.59", 0.0]}, "ior[0]"),
    ({**GOOD, "ior": [0.0, 0.0]}, "ior[0]"),
    ({**GOOD, "ior": [10.5, 0.0]}, "ior[0]"),
    ({**GOOD, "ior": [float("nan"), 0.0]}, "ior[0]"),
    ({**GOOD, "ior": [1.59, -0.1]}, "ior[1]"),
    ({**GOOD, "ior": [1.59, 11.0]}, "ior[1]"),
    ({**GOOD, "ior": [1.59, False]}, "ior[1]"),
    ({**GOOD, "number_per_m3": 0}, "number_per_m3"),
    ({**GOOD, "number_per_m3": -5.0}, "number_per_m3"),
    ({**GOOD, "number_per_m3": 1e31}, "number_per_m3"),
    ({**GOOD, "number_per_m3": True}, "number_per_m3"),
    ({**GOOD, "number_per_m3": None}, "number_per_m3"),
    ({**GOOD, "number_per_m3": float("inf")}, "number_per_m3"),
]


@pytest.mark.parametrize(("body", "field"), BAD)
def test_bad_bodies_name_the_field(body, field):
    with pytest.raises(MaterialError) as err:
        mie.parse_particles(body, "particles", "material m1")
    assert field in str(err.value) and "material m1" in str(err.value)


def test_limits_that_need_the_host():
    """x ≤ X_MAX: r = 1000 µm in glass of index 3 has x = 5.2e4 at 360 nm; σ_ext ≤ 1e9 1/m: 1e21 spheres of 1 µm per
    m³ give 3.1e9·Q_ext. Both are refused before any table is built, naming the field."""
    with pytest.raises(MaterialError, match="radius_um"):
        mie.mie_table(mie.Particles(1000.0, 1.5, 0.0, 1.0), np.full(GRID_N, 3.0))
    with pytest.raises(MaterialError, match="number_per_m3"):
        mie.mie_table(mie.Particles(1.0, 1.5, 0.0, 1e21), np.full(GRID_N, 1.0))
    with pytest.raises(ValueError):
        mie.mie_table(mie.Particles(1.0, 1.5, 0.0, 1e10), np.ones(10))
