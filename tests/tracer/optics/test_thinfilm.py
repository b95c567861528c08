"""Thin-film stacks (tracer.optics.thinfilm): published values, Fresnel limits, energy, reciprocity, and `tmm`.

Reference figures are those of docs/REFERENCES.md ("Thin films", "Fresnel and polarization").
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from numba import njit

from tracer.optics.thinfilm import stack_reflectance, stack_rt

AIR, GLASS, MGF2, TIO2, SIO2 = 1.0, 1.52, 1.38, 2.35, 1.46
ALUMINIUM = (0.96, 6.69)  # n, k of an Al-like metal at ~550 nm


def layers(rows) -> np.ndarray:
    """A (m, 2) float64 array of [n, thickness nm] rows (m may be 0)."""
    return np.array(rows, dtype=np.float64).reshape(-1, 2)


def quarter_wave(n: float, lam: float = 550.0) -> list[float]:
    return [n, lam / (4.0 * n)]


def fresnel(n1: float, n2: float, theta: float) -> tuple[float, float]:
    """Exact Rs, Rp of a bare lossless interface (below the critical angle)."""
    ci = math.cos(theta)
    ct = math.sqrt(1.0 - (n1 * math.sin(theta) / n2) ** 2)
    rs = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct)
    rp = (n2 * ci - n1 * ct) / (n2 * ci + n1 * ct)
    return rs * rs, rp * rp


def random_stack(rng: np.random.Generator, max_layers: int = 8) -> np.ndarray:
    m = int(rng.integers(0, max_layers + 1))
    return layers(np.column_stack([rng.uniform(1.2, 2.6, m), rng.uniform(0.0, 400.0, m)]))


@pytest.fixture(scope="module", autouse=True)
def first_call() -> tuple[float, bool]:
    """Seconds taken by the first call of stack_rt in this process, and whether numba's cache supplied it."""
    start = time.perf_counter()
    stack_rt(layers([quarter_wave(MGF2)]), 0, 1, False, AIR, GLASS, 0.0, 550.0, 1.0)
    seconds = time.perf_counter() - start
    return seconds, sum(stack_rt.stats.cache_hits.values()) > 0


# 1. published values and closed forms


def test_mgf2_quarter_wave_on_glass() -> None:
    mgf2 = layers([quarter_wave(MGF2)])
    assert mgf2[0, 1] == pytest.approx(99.638, abs=5e-4)
    closed = ((AIR * GLASS - MGF2**2) / (AIR * GLASS + MGF2**2)) ** 2
    r550 = stack_reflectance(mgf2, 0, 1, False, AIR, GLASS, 0.0, 550.0, 1.0)
    assert abs(r550 - closed) < 1e-12
    for lam, percent in ((550.0, 1.2601), (450.0, 1.6204), (650.0, 1.4368)):
        assert abs(100.0 * stack_reflectance(mgf2, 0, 1, False, AIR, GLASS, 0.0, lam, 1.0) - percent) < 5e-5
    assert abs(100.0 * stack_reflectance(mgf2, 0, 0, False, AIR, GLASS, 0.0, 550.0, 1.0) - 4.2580) < 5e-5
    rs, rp, _, _ = stack_rt(mgf2, 0, 1, False, AIR, GLASS, 0.0, 550.0, math.cos(math.radians(45.0)))
    assert abs(100.0 * rs - 4.0048) < 5e-5
    assert abs(100.0 * rp - 0.1356) < 5e-5


@pytest.mark.parametrize(("pairs", "cap", "expected"), [(3, False, 0.859501), (5, False, 0.977706),
                                                        (5, True, 0.990612)])
def test_quarter_wave_high_reflector(pairs: int, cap: bool, expected: float) -> None:
    rows = [quarter_wave(TIO2), quarter_wave(SIO2)] * pairs + ([quarter_wave(TIO2)] if cap else [])
    stack = layers(rows)
    r = stack_reflectance(stack, 0, len(rows), False, AIR, GLASS, 0.0, 550.0, 1.0)
    assert abs(r - expected) < 5e-7


# 2. a bare interface is Fresnel


@pytest.mark.parametrize(("n1", "n2"), [(1.0, 1.5), (1.5, 1.0), (1.33, 2.4)])
def test_bare_interface_is_fresnel(n1: float, n2: float) -> None:
    for degrees in (0.0, 10.0, 30.0, 41.0, 45.0, 60.0, 80.0, 89.0):
        theta = math.radians(degrees)
        if n1 * math.sin(theta) >= n2:
            continue  # beyond the critical angle: test_total_internal_reflection
        rs, rp, ts, tp = stack_rt(layers([]), 0, 0, False, n1, n2, 0.0, 550.0, math.cos(theta))
        es, ep = fresnel(n1, n2, theta)
        assert abs(rs - es) < 1e-14 and abs(rp - ep) < 1e-14
        assert abs(ts - (1.0 - es)) < 1e-14 and abs(tp - (1.0 - ep)) < 1e-14


def test_bare_interface_published_values() -> None:
    bare = layers([])
    assert abs(stack_reflectance(bare, 0, 0, False, 1.0, 1.5, 0.0, 550.0, 1.0) - 0.04) < 1e-15
    rs, rp, _, _ = stack_rt(bare, 0, 0, False, 1.0, 1.5, 0.0, 550.0, math.cos(math.radians(45.0)))
    assert abs(rs - 0.092013) < 5e-7 and abs(rp - 0.008466) < 5e-7
    rs, rp, _, tp = stack_rt(bare, 0, 0, False, 1.0, 1.5, 0.0, 550.0, math.cos(math.atan(1.5)))
    assert rp < 1e-12 and abs(tp - 1.0) < 1e-12
    assert abs(rs - 0.147929) < 5e-7


def test_same_medium_without_layers_reflects_nothing() -> None:
    for cos_in in (1.0, 0.7, 0.123, 0.0):
        assert stack_rt(layers([]), 0, 0, False, 1.52, 1.52, 0.0, 500.0, cos_in) == (0.0, 0.0, 1.0, 1.0)


# 3. energy


def test_lossless_stacks_conserve_energy() -> None:
    rng = np.random.default_rng(20261101)
    for _ in range(200):
        stack = random_stack(rng)
        n_in, n_out = rng.uniform(1.0, 1.8), rng.uniform(1.0, 2.6)  # includes evanescent layers and exits
        cos_in = math.cos(rng.uniform(0.0, math.radians(89.0)))
        rs, rp, ts, tp = stack_rt(stack, 0, len(stack), bool(rng.integers(2)), n_in, n_out, 0.0,
                                  rng.uniform(380.0, 780.0), cos_in)
        assert abs(rs + ts - 1.0) < 1e-12 and abs(rp + tp - 1.0) < 1e-12
        assert 0.0 <= min(rs, rp, ts, tp) and max(rs, rp, ts, tp) <= 1.0


# 4. reciprocity and total internal reflection


def test_transmittance_is_the_same_both_ways() -> None:
    rng = np.random.default_rng(7)
    for _ in range(100):
        stack = random_stack(rng)
        m = len(stack)
        padded = np.vstack([layers([[9.0, 9.0]] * 2), stack, layers([[9.0, 9.0]] * 3)])  # rows 2 .. 2+m-1
        ambient, substrate = rng.uniform(1.0, 1.4), rng.uniform(1.4, 2.0)
        lam = rng.uniform(380.0, 780.0)
        theta_a = rng.uniform(0.0, math.radians(89.0))
        theta_s = math.asin(ambient * math.sin(theta_a) / substrate)  # Snell
        front = stack_rt(padded, 2, m, False, ambient, substrate, 0.0, lam, math.cos(theta_a))
        back = stack_rt(padded, 2, m, True, substrate, ambient, 0.0, lam, math.cos(theta_s))
        np.testing.assert_allclose(back[2:], front[2:], rtol=0, atol=1e-12)  # Ts, Tp
        np.testing.assert_allclose(back[:2], front[:2], rtol=0, atol=1e-12)  # hence Rs, Rp (lossless)


@pytest.mark.parametrize("rows", [[], [quarter_wave(MGF2)], [quarter_wave(TIO2)],
                                  [quarter_wave(TIO2), quarter_wave(SIO2), [1.25, 300.0]]])
def test_total_internal_reflection(rows) -> None:
    stack = layers(rows)
    critical = math.asin(AIR / GLASS)
    for degrees in (42.0, 50.0, 65.0, 80.0, 89.0):
        assert math.radians(degrees) > critical
        for lam in (400.0, 550.0, 700.0):
            rs, rp, ts, tp = stack_rt(stack, 0, len(rows), True, GLASS, AIR, 0.0, lam, math.cos(math.radians(degrees)))
            assert abs(rs - 1.0) < 1e-12 and abs(rp - 1.0) < 1e-12
            assert ts == 0.0 and tp == 0.0


# 5. the `tmm` package


def test_agrees_with_tmm() -> None:
    tmm = pytest.importorskip("tmm")
    rng = np.random.default_rng(1603_02720)
    for case in range(100):
        stack = random_stack(rng)
        reverse = bool(rng.integers(2))
        n_in = rng.uniform(1.0, 1.8)
        exits = [(rng.uniform(1.0, 2.6), 0.0), ALUMINIUM, (rng.uniform(0.1, 3.0), rng.uniform(0.0, 8.0))]
        n_out, k_out = exits[case % 3]  # glass-like, aluminium-like, any absorber
        theta = rng.uniform(0.0, math.radians(89.0))
        lam = rng.uniform(380.0, 780.0)
        ours = stack_rt(stack, 0, len(stack), reverse, n_in, n_out, k_out, lam, math.cos(theta))
        crossed = stack[::-1] if reverse else stack
        # tmm takes absorbing media as n + ik (time dependence e^{-iωt}); ours is n − ik: R and T are the same
        n_list = [n_in, *crossed[:, 0], complex(n_out, k_out)]
        d_list = [np.inf, *crossed[:, 1], np.inf]
        s, p = (tmm.coh_tmm(pol, n_list, d_list, theta, lam) for pol in "sp")
        np.testing.assert_allclose(ours, [s["R"], p["R"], s["T"], p["T"]], rtol=0, atol=1e-9)


def test_coated_metal_mirror() -> None:
    n, k = ALUMINIUM
    bare = ((1.0 - n) ** 2 + k**2) / ((1.0 + n) ** 2 + k**2)
    half_wave = layers([[SIO2, 550.0 / (2.0 * SIO2)]])  # an absentee layer at normal incidence
    assert abs(stack_reflectance(half_wave, 0, 1, False, AIR, n, k, 550.0, 1.0) - bare) < 1e-12
    assert abs(stack_reflectance(half_wave, 0, 0, False, AIR, n, k, 550.0, 1.0) - bare) < 1e-12
    rs, rp, ts, tp = stack_rt(layers([quarter_wave(SIO2)]), 0, 1, False, AIR, n, k, 550.0, math.cos(math.radians(30.0)))
    assert 0.0 < ts < 1.0 and 0.0 < tp < 1.0  # the metal absorbs what it takes in
    assert abs(rs + ts - 1.0) < 1e-12 and abs(rp + tp - 1.0) < 1e-12  # lossless layer: nothing else is lost


# 6. inside a kernel


@njit(error_model="numpy", _nrt=False)
def _reflectance_spectrum(stack, lams, out):
    for i in range(lams.size):
        out[i] = stack_reflectance(stack, 0, stack.shape[0], False, 1.0, 1.52, 0.0, lams[i], 1.0)


def test_compiles_inside_a_jitted_caller(first_call, capsys) -> None:
    stack = layers([quarter_wave(MGF2)])
    lams = np.linspace(400.0, 700.0, 7)
    out = np.empty_like(lams)
    _reflectance_spectrum(stack, lams, out)
    expected = [stack_reflectance(stack, 0, 1, False, 1.0, 1.52, 0.0, lam, 1.0) for lam in lams]
    assert out.tolist() == expected
    seconds, cached = first_call
    with capsys.disabled():
        print(f"\nstack_rt first call: {seconds:.3f} s ({'loaded from numba cache' if cached else 'compiled'})")
