"""χ² tests of the sampled directions against the evaluated densities, as Mitsuba 3's
`src/python/python/chi2.py` (``ChiSquareTest``) does, for `microfacet` (isotropic and brushed), a rough `dielectric`
and `measured_brdf`.

The kinds only sample (`scatter`); the density they promise is written here from each one's documented formula,
independently of the kernels: GGX's reflection and Walter's transmission in `ggx_reference.density` (the papers'
equations), and the measured table's piecewise-constant f(θi interpolated; θo, Δφ) cosθo. A photon is sampled
through the switch the transport kernel inlines (`scatter_contract.Case`); it either leaves along a direction or is
absorbed (the analog kinds weigh every survivor 1), so the density integrates to the albedo and "absorbed" is one
more outcome with probability 1 − albedo.

- Directions are binned over an equal-area (cos θ, φ) grid (cos θ over [0, 1] for a reflector, [−1, 1] for the
  dielectric); each bin's expected count is N × the density integrated over it (midpoint rule, 8 × 8 sub-cells;
  for the table: its cells split in two along cos²θ and Δφ, where the density is exactly constant);
- bins expecting fewer than 5 photons are pooled into one (Mitsuba's ``min_exp_frequency``), then Pearson's χ²
  with (bins − 1) degrees of freedom and its p-value from `scipy.stats.chi2`;
- each test passes at significance 0.01 corrected for the number of tests (Šidák, as Mitsuba:
  1 − (1 − 0.01)^(1/n)).

The tests are seen to fail where the sampler and the density disagree: `test_a_wrong_density_is_rejected` evaluates
the density with α 15 % off (GGX) or the table's Δφ read the wrong way round, and requires a p-value below 1e-6.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from ggx_reference import density
from scatter_contract import Case
from scipy import stats

from tracer.optics.surfaces import dielectric, measured_brdf, microfacet
from tracer.optics.surfaces.base import CONTINUES, spec_from_body

WHITE = ("white", 0.0, 0.0, 0.0, 0.0)
N = 200_000            # photons per test
SUB = 8                # midpoint sub-cells per bin side
MIN_EXPECTED = 5.0     # Mitsuba's min_exp_frequency


def arriving(theta_deg: float, phi: float = 0.0, side: str = "front") -> np.ndarray:
    t = math.radians(theta_deg)
    w = np.array([math.sin(t) * math.cos(phi), math.sin(t) * math.sin(phi), math.cos(t)])
    return -w if side == "front" else w


def spec_of(module, **body):
    return spec_from_body(module.Spec, module.NAME, {"type": module.NAME, **body}, "chi2")


# a measured table with structure along θo and Δφ, and three θi rows, so interpolation and the Δφ sense both show
TABLE_TO = [0, 20, 40, 60, 75, 90]
TABLE_DP = [0, 30, 90, 150, 180]


def _table() -> dict:
    rows = []
    for i in range(3):   # the rows θi = 0, 40, 80
        rows.append([[0.05 + 0.04 * (1 + i) * (k + 1) * (1 + j) / 20 for k in range(len(TABLE_DP) - 1)]
                     for j in range(len(TABLE_TO) - 1)])
    return {"theta_i_deg": [0, 40, 80], "theta_o_deg": TABLE_TO, "dphi_deg": TABLE_DP, "brdf": rows}


# (name, module, body, θi, φi, side, cos θ range, bins in cos θ × φ)
CASES = [
    ("microfacet α=0.3 at 0°", microfacet, {"alpha": 0.3, "reflectance": 1.0}, 0.0, 0.0, "front", (0, 1), (24, 24)),
    ("microfacet α=0.3 at 50°", microfacet, {"alpha": 0.3, "reflectance": 0.8}, 50.0, 0.4, "front", (0, 1),
     (24, 24)),
    ("microfacet α=0.6 at 75°", microfacet, {"alpha": 0.6, "reflectance": 1.0}, 75.0, 0.0, "front", (0, 1),
     (24, 24)),
    ("microfacet brushed 0.15/0.5 at 0°", microfacet,
     {"alpha": 0.15, "alpha_y": 0.5, "axis": [1, 0, 0], "reflectance": 1.0}, 0.0, 0.0, "front", (0, 1), (24, 24)),
    ("microfacet brushed 0.15/0.5 at 45°", microfacet,
     {"alpha": 0.15, "alpha_y": 0.5, "axis": [1, 0, 0], "reflectance": 1.0}, 45.0, 0.7, "front", (0, 1), (24, 24)),
    ("rough dielectric α=0.3 at 30° into glass", dielectric, {"ior": 1.5, "alpha": 0.3}, 30.0, 0.0, "front",
     (-1, 1), (40, 24)),
    ("rough dielectric α=0.5 at 60° into glass", dielectric, {"ior": 1.5, "alpha": 0.5}, 60.0, 0.3, "front",
     (-1, 1), (40, 24)),
    ("rough dielectric α=0.3 at 20° out of glass", dielectric, {"ior": 1.5, "alpha": 0.3}, 20.0, 0.0, "back",
     (-1, 1), (40, 24)),
    ("rough dielectric α=0.4 at 50° out of glass (TIR)", dielectric, {"ior": 1.5, "alpha": 0.4}, 50.0, 0.0,
     "back", (-1, 1), (40, 24)),
    ("rough dielectric brushed 0.1/0.4 at 45°", dielectric,
     {"ior": 1.5, "alpha": 0.1, "alpha_y": 0.4, "axis": [1, 0, 0]}, 45.0, 1.1, "front", (-1, 1), (40, 24)),
    ("measured_brdf at 25°", measured_brdf, {"table": _table()}, 25.0, 0.0, "front", None, None),
    ("measured_brdf at 62°", measured_brdf, {"table": _table()}, 62.0, 0.9, "front", None, None),
]
SIGNIFICANCE = 1.0 - (1.0 - 0.01) ** (1.0 / len(CASES))


# ------------------------------------------------------------------------------------------ the statistics


def pearson(observed: np.ndarray, expected: np.ndarray) -> tuple[float, int, float]:
    """(χ², degrees of freedom, p-value) with the bins expecting < MIN_EXPECTED pooled into one (Mitsuba's
    `ChiSquareTest.run`)."""
    observed, expected = np.ravel(observed).astype(float), np.ravel(expected)
    low = expected < MIN_EXPECTED
    obs = np.append(observed[~low], observed[low].sum())
    exp = np.append(expected[~low], expected[low].sum())
    if exp[-1] < MIN_EXPECTED:   # the pooled bin still too small: merge it into the smallest kept one
        k = int(np.argmin(exp[:-1]))
        obs[k] += obs[-1]
        exp[k] += exp[-1]
        obs, exp = obs[:-1], exp[:-1]
    chi2 = float(np.sum((obs - exp) ** 2 / exp))
    dof = len(obs) - 1
    return chi2, dof, float(stats.chi2.sf(chi2, dof))


def local(case_side: str, wo: np.ndarray) -> np.ndarray:
    """World directions in the arrival side's frame (z towards the photon's origin side; a mirror image from the
    back, which an isotropic density does not see)."""
    return wo if case_side == "front" else wo * np.array([1.0, 1.0, -1.0])


def ggx_counts(case: Case, module, body, side, crange, bins, n, wrong_alpha=1.0):
    """(observed, expected) counts over the (cos θ, φ) grid plus the absorbed outcome."""
    out, _ = case.run(n=n, seed=17)
    alive = out[:, 0] == CONTINUES
    assert np.all(out[alive, 4] == 1.0)   # analog: every survivor carries weight 1
    wo = local(side, out[alive, 1:4])
    nc, nph = bins
    lo, hi = crange
    phi = np.arctan2(wo[:, 1], wo[:, 0]) % (2 * math.pi)
    obs = np.histogram2d(wo[:, 2], phi, bins=(nc, nph), range=((lo, hi), (0, 2 * math.pi)))[0]
    # the density on SUB × SUB midpoints of every bin
    c = lo + (np.arange(nc * SUB) + 0.5) * (hi - lo) / (nc * SUB)
    p = (np.arange(nph * SUB) + 0.5) * 2 * math.pi / (nph * SUB)
    cc, pp = np.meshgrid(c, p, indexing="ij")
    s = np.sqrt(1 - cc * cc)
    grid = np.stack([s * np.cos(pp), s * np.sin(pp), cc], -1)
    wi = -local(side, case.d)
    ax = body["alpha"] * wrong_alpha
    ay = body.get("alpha_y", body["alpha"]) * wrong_alpha
    if module is microfacet:
        pr, pt = density(wi, grid, ax, ay, reflectance=body["reflectance"])
    else:
        n1, n2 = (1.0, body["ior"]) if side == "front" else (body["ior"], 1.0)
        pr, pt = density(wi, grid, ax, ay, n1=n1, n2=n2)
    dw = (hi - lo) / (nc * SUB) * 2 * math.pi / (nph * SUB)
    exp = ((pr + pt) * dw).reshape(nc, SUB, nph, SUB).sum(axis=(1, 3)) * n
    return np.append(obs.ravel(), n - alive.sum()), np.append(exp.ravel(), max(n - exp.sum(), 0.0))


def table_counts(case: Case, body, n, flip_dphi=False):
    """(observed, expected) counts over the table's cells, each split in two along cos²θ and along Δφ, for both
    signs of Δφ, plus the absorbed outcome. The expected density of a photon arriving at θi between rows j, j + 1
    (weights 1 − t, t, linear in θi) is f_interp cos θo (the module's docstring)."""
    out, _ = case.run(n=n, seed=17)
    alive = out[:, 0] == CONTINUES
    assert np.all(out[alive, 4] == 1.0)
    wo = out[alive, 1:4]
    table = spec_of(measured_brdf, **body).table
    f = table.values()
    ti = np.array(table.theta_i_deg)
    theta = math.degrees(math.acos(-case.d[2]))
    j = min(int(np.searchsorted(ti, theta, side="right")) - 1, len(ti) - 2)
    t = (theta - ti[j]) / (ti[j + 1] - ti[j])
    fi = (1 - t) * f[j] + t * f[j + 1]                     # (n_o, n_p)
    if flip_dphi:
        fi = fi[:, ::-1]
    # edges: cos²θ halves of each θo bin, Δφ halves of each Δφ bin
    mu2 = np.cos(np.radians(TABLE_TO)) ** 2
    mu2[-1] = 0.0
    mu2_edges = np.sort(np.concatenate([mu2, (mu2[:-1] + mu2[1:]) / 2]))     # increasing cos² (θ decreasing)
    dp = np.radians(TABLE_DP)
    dp_edges = np.sort(np.concatenate([dp, (dp[:-1] + dp[1:]) / 2]))
    src = -case.d
    dphi = np.arctan2(wo[:, 1], wo[:, 0]) - math.atan2(src[1], src[0])
    dphi = (dphi + math.pi) % (2 * math.pi) - math.pi            # signed, in (−π, π]
    signed_edges = np.concatenate([-dp_edges[::-1], dp_edges[1:]])
    obs = np.histogram2d(wo[:, 2] ** 2, dphi, bins=(mu2_edges, signed_edges))[0]
    # expected: f(cell) × (Δcos²/2) × Δφ per sub-cell; cell of a sub-cell by its midpoint
    mid_mu2 = (mu2_edges[:-1] + mu2_edges[1:]) / 2
    io = np.searchsorted(-mu2[:-1], -mid_mu2, side="right") - 1      # θo bin: mu2 decreasing along the table
    mid_dp = np.abs((signed_edges[:-1] + signed_edges[1:]) / 2)
    ip = np.searchsorted(dp, mid_dp, side="right") - 1
    exp = fi[io][:, ip] * np.outer(np.diff(mu2_edges) / 2, np.diff(signed_edges)) * n
    return np.append(obs.ravel(), n - alive.sum()), np.append(exp.ravel(), max(n - exp.sum(), 0.0))


def counts(name, module, body, theta, phi, side, crange, bins, n=N, wrong=False):
    case = Case(module, spec_of(module, **body), side, theta, arriving(theta, phi, side), WHITE)
    if module is measured_brdf:
        return table_counts(case, body, n, flip_dphi=wrong)
    return ggx_counts(case, module, body, side, crange, bins, n, wrong_alpha=1.15 if wrong else 1.0)


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_sampled_directions_follow_the_evaluated_density(case):
    obs, exp = counts(*case)
    assert abs(exp.sum() - obs.sum()) < 1e-6 * obs.sum() + 1.0
    chi2, dof, p = pearson(obs, exp)
    assert p > SIGNIFICANCE, f"{case[0]}: χ² = {chi2:.1f} with {dof} dof, p = {p:.2e} < {SIGNIFICANCE:.2e}"


@pytest.mark.parametrize("case", [CASES[1], CASES[3], CASES[6], CASES[10]], ids=lambda c: c[0])
def test_a_wrong_density_is_rejected(case):
    """The test has power: α 15 % off (GGX) or Δφ read the wrong way round (the table) fails by far."""
    chi2, dof, p = pearson(*counts(*case, wrong=True))
    assert p < 1e-6, f"{case[0]}: a wrong density passed (χ² = {chi2:.1f}, {dof} dof, p = {p:.2e})"


def test_walters_transmission_is_reciprocal():
    """Walter et al. eq. 21's generalized reciprocity, f_t(i → o) / n_o² = f_t(o → i) / n_i² (densities here are
    f |cos θo|), and f_r(i → o) = f_r(o → i), on random pairs of directions (the sampler is held to these densities
    by the χ² tests above)."""
    rng = np.random.default_rng(1)
    for _ in range(200):
        wi = rng.normal(size=3)
        wi[2] = abs(wi[2])
        wi /= np.linalg.norm(wi)
        wo = rng.normal(size=3)
        wo /= np.linalg.norm(wo)
        ax, ay = rng.uniform(0.05, 1.0, 2)
        n1, n2 = 1.0, 1.5
        pr, pt = density(wi, wo, ax, ay, n1=n1, n2=n2)
        back = -wo if wo[2] < 0 else wo            # o seen from its own side
        wi_b = wi if wo[2] > 0 else -wi
        qr, qt = density(back, wi_b, ax, ay, n1=n1 if wo[2] > 0 else n2, n2=n2 if wo[2] > 0 else n1)
        if wo[2] > 0:
            assert pr / abs(wo[2]) == pytest.approx(qr / abs(wi[2]), rel=1e-9, abs=1e-12)
        else:
            assert pt / abs(wo[2]) / n2 ** 2 == pytest.approx(qt / abs(wi[2]) / n1 ** 2, rel=1e-9, abs=1e-12)
