"""A density map's sites placed as blue noise (`tracer.elements.placement`, issue 53): error diffusion keeps each map
cell's fill up to what crosses the cell's edges, and its local count varies with a window's perimeter, not its area.

For sites kept independently with probability f, the count in a w x w window has variance w² f (1 - f): its standard
deviation doubles when w doubles. A blue-noise (hyperuniform) pattern's count variance grows with the perimeter,
~w, so its standard deviation grows by about sqrt(2) per doubling (Torquato and Stillinger, Phys. Rev. E 68, 041113
(2003)). The checks below take w from 8 to 32 sites (a factor 4): area scaling gives 4, perimeter scaling 2; the
line between them is their geometric mean, 2.83, and the random placement is held to the other side of it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tracer.elements import ElementError, prepare

PITCH = 0.1


def lattice(fill, nu=400, nv=400, seed=1, placement=None) -> tuple[np.ndarray, object]:
    """(kept sites as an (nv, nu) bool array, rows along v, the prepared element) of a dome density layout."""
    layout = {"type": "density", "origin_mm": [0, 0], "size_mm": [(nu + 0.5) * PITCH, (nv + 0.5) * PITCH], "fill": fill,
              "seed": seed, "pitch_mm": PITCH}
    if placement is not None:
        layout["placement"] = placement
    e = prepare({"type": "microstructure", "feature": {"shape": "dome", "radius_mm": 0.04, "height_mm": 0.01},
                 "layout": layout})
    assert e.cells == (nu, nv)
    kept = np.unpackbits(e.bits, bitorder="little")[:nu * nv].reshape(nv, nu).astype(bool)
    assert int(kept.sum()) == e.features
    return kept, e


def window_std(kept: np.ndarray, w: int) -> float:
    """Standard deviation of the kept count over the lattice's disjoint w x w windows."""
    n, m = kept.shape[0] // w, kept.shape[1] // w
    return float(kept[:n * w, :m * w].reshape(n, w, m, w).sum(axis=(1, 3)).std())


def test_the_default_placement_is_blue_noise_and_an_explicit_random_one_keeps_its_former_id():
    """A density body without a placement was placed at random before placements (and had the id below, from the
    code before them); it now means blue noise, so it has another id, and the explicit random body has the former
    one: an element a library holds keeps its id and its bits."""
    body = {"type": "microstructure", "feature": {"shape": "dome", "radius_mm": 0.04, "height_mm": 0.01},
            "layout": {"type": "density", "origin_mm": [0, 0], "size_mm": [40.05, 40.05], "fill": [[0.3]], "seed": 1,
                       "pitch_mm": 0.1}}
    former = "7566f2cd9790e10b9828c9faa3f7ec794dcb5fa834b7e0abda06f39da24d54b8"
    e = prepare(body)
    assert e.body["layout"]["placement"] == "blue_noise" and e.id != former
    r = prepare({**body, "layout": {**body["layout"], "placement": "random"}})
    assert "placement" not in r.body["layout"] and r.id == former


@pytest.mark.parametrize("f", [0.05, 0.3, 0.5, 0.8])
def test_blue_noise_varies_with_a_window_s_perimeter_and_random_sites_with_its_area(f):
    blue, _ = lattice([[f]])
    rand, _ = lattice([[f]], placement="random")
    binomial = math.sqrt(32 * 32 * f * (1 - f))
    growth_blue = window_std(blue, 32) / window_std(blue, 8)
    growth_random = window_std(rand, 32) / window_std(rand, 8)
    assert growth_blue < 2.83 < growth_random, (growth_blue, growth_random)
    # a 32 x 32 window (a 3.2 mm spot at 0.1 mm pitch) varies less than half as much as independent sites would
    # (measured 0.29 of it at f = 0.05, 0.13 at 0.3)
    assert window_std(blue, 32) < 0.5 * binomial, (window_std(blue, 32), binomial)
    assert window_std(rand, 32) == pytest.approx(binomial, rel=0.25)   # 156 windows: the estimate's own spread


def test_each_map_cell_keeps_its_fill_up_to_the_error_crossing_its_edges():
    """A fed-forward error is at most one feature per site, so a cell of N sites keeps f N up to its perimeter in
    sites (the errors leaving across its edges); the whole lattice keeps its total up to what left its last row and
    its sides. (Measured: cells within 78 features of 200 x 200 sites, the total within 3.)"""
    fill = [[0.1, 0.5, 0.25], [0.9, 0.02, 0.7]]
    kept, _ = lattice(fill, nu=600, nv=400)
    for r, row in enumerate(fill):
        for c, f in enumerate(row):
            cell = kept[r * 200:(r + 1) * 200, c * 200:(c + 1) * 200]
            assert abs(int(cell.sum()) - f * cell.size) <= 4 * 200, (r, c, int(cell.sum()), f * cell.size)
    total = sum(f for row in fill for f in row) * 200 * 200
    assert abs(int(kept.sum()) - total) <= 600 + 2 * 400   # what left the lattice's last row and side edges


def test_a_seed_gives_another_pattern_of_the_same_statistics_and_the_same_seed_the_same_bits():
    a, ea = lattice([[0.3]], seed=1)
    b, eb = lattice([[0.3]], seed=2)
    again, _ = lattice([[0.3]], seed=1)
    assert np.array_equal(a, again)
    assert ea.id != eb.id and np.mean(a != b) > 0.1
    assert window_std(b, 32) < 0.5 * math.sqrt(32 * 32 * 0.21)


def test_an_unknown_placement_is_refused_naming_the_field():
    with pytest.raises(ElementError, match=r"layout.placement must be one of \['blue_noise', 'random'\]"):
        lattice([[0.3]], placement="poisson")
