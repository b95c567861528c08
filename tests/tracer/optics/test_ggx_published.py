"""`microfacet` (GGX, F = 1) against a published table of its directional albedo E(μ): Blender Cycles'
`table_ggx_E` (docs/GGX_REFERENCE.md has the source, its parameters μ = y/31, α = (x/31)², and the rows).

- The table's rows as printed (docs/GGX_REFERENCE.md, transcribed here) agree with an independent midpoint-rule
  integral of E(μ) (`ggx_reference.albedo`, F = 1) within TABLE_TOL, the table's rounding (5e-7) plus its own
  Monte Carlo error (2²³ Sobol samples per cell; the largest difference seen here is about 1e-6; the integral's
  own error is below 1e-6 at the resolutions used: 1000 × 1600 cells in (θ, φ), 8000 × 8 at μ = 1);
- the tracer's `microfacet` with reflectance 1, through the switch the transport kernel inlines, keeps E(μ) of the
  table within 4σ of its estimate plus TABLE_TOL, at μ = 1, 0.4839 and 0.1935 and α = 0.0375, 0.1759, 0.5036, 1.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from ggx_reference import albedo
from scatter_contract import Case, mean_and_error

from tracer.optics.surfaces import microfacet
from tracer.optics.surfaces.base import CONTINUES, spec_from_body

K = 4.0
N = 20_000
TABLE_TOL = 5e-6   # the table's 6 decimals (5e-7) and its own Monte Carlo error, bounded by the integral check
WHITE = ("white", 0.0, 0.0, 0.0, 0.0)

# table_ggx_E rows y = 6, 15, 31 (μ = y/31), columns x = 0 … 31 (α = (x/31)²), as printed in the source
ROWS = {
    6: "1.000000 0.999985 0.999752 0.998684 0.995603 0.988803 0.976727 0.959272 0.938451 0.917446 0.898932 0.884154 "
       "0.873043 0.864773 0.858278 0.852565 0.846845 0.840555 0.833331 0.824969 0.815378 0.804550 0.792533 0.779405 "
       "0.765271 0.750246 0.734447 0.717996 0.701008 0.683595 0.665862 0.647905",
    15: "1.000000 0.999997 0.999954 0.999762 0.999228 0.998053 0.995814 0.991966 0.985893 0.977026 0.964995 0.949768 "
        "0.931677 0.911324 0.889415 0.866586 0.843295 0.819794 0.796153 0.772321 0.748187 0.723632 0.698566 0.672945 "
        "0.646780 0.620134 0.593114 0.565860 0.538532 0.511298 0.484328 0.457779",
    31: "1.000000 0.999999 0.999983 0.999911 0.999716 0.999296 0.998513 0.997184 0.995072 0.991884 0.987261 0.980785 "
        "0.971982 0.960355 0.945407 0.926694 0.903873 0.876756 0.845349 0.809871 0.770757 0.728630 0.684249 0.638454 "
        "0.592102 0.546006 0.500893 0.457373 0.415925 0.376893 0.340499 0.306853",
}
COLUMNS = (6, 13, 22, 31)
CELLS = [(y, x) for y in ROWS for x in COLUMNS]


def cell(y: int, x: int) -> tuple[float, float, float]:
    """(μ, α, E) of one table cell."""
    return y / 31, (x / 31) ** 2, float(ROWS[y].split()[x])


def test_the_table_rows_have_32_values_and_their_known_ends():
    for y, row in ROWS.items():
        v = np.array(row.split(), float)
        assert len(v) == 32 and v[0] == 1.0 and np.all(np.diff(v) < 0), y   # E falls as α grows


@pytest.mark.parametrize(("y", "x"), CELLS)
def test_the_published_table_is_the_single_scattering_albedo(y, x):
    mu, alpha, e = cell(y, x)
    wi = np.array([math.sqrt(1 - mu * mu), 0.0, mu])
    # at μ = 1 the integrand does not depend on φ but peaks at the pole: fine in θ, coarse in φ
    res = (8000, 8) if y == 31 else (1000, 1600)
    r, _ = albedo(wi, alpha, alpha, *res, reflectance=1.0)
    assert abs(r - e) <= TABLE_TOL, (mu, alpha, r, e)


@pytest.mark.parametrize(("y", "x"), CELLS)
def test_microfacet_keeps_the_published_albedo(y, x):
    mu, alpha, e = cell(y, x)
    d = -np.array([math.sqrt(1 - mu * mu), 0.0, mu])
    s = spec_from_body(microfacet.Spec, "microfacet", {"type": "microfacet", "alpha": alpha, "reflectance": 1.0},
                       "test")
    out, _ = Case(microfacet, s, "front", math.degrees(math.acos(mu)), d, WHITE).run(n=N, seed=31 + x)
    mean, err = mean_and_error(np.where(out[:, 0] == CONTINUES, out[:, 4], 0.0))
    assert abs(mean - e) <= K * max(err, math.sqrt(e * (1 - e) / N)) + TABLE_TOL, (mu, alpha, mean, err, e)
