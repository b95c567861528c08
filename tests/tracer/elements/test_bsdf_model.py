"""An element used through its tabulated BSDF (tracer.elements.bsdf) against the same element traced exactly: the
table's rows sum to what leaves, an ideal prism film's near-normal row returns its light, and a dotted PMMA plate
transmits the same flux with either model within the Monte Carlo errors plus the table's resolution error (issue
36)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.tracer.transport_scenes import box
from tracer.elements import ElementError, prepare
from tracer.elements import bsdf as tab
from tracer.scene import Scene
from tracer.simulate import Simulation

PMMA = {"type": "dielectric", "ior": 1.49}
DOTS = {"type": "microstructure", "feature": {"shape": "dome", "radius_mm": 0.08, "height_mm": 0.04},
        "layout": {"type": "grid", "pitch_mm": [0.2, 0.2]}}


def test_a_table_row_holds_what_leaves_and_a_prism_film_returns_near_normal_light():
    film = prepare({"type": "microstructure", "feature": {"shape": "prism", "base_mm": 0.05, "apex_deg": 90},
                    "layout": {"type": "grid", "pitch_mm": [0.05, 0.05]}})
    t = tab.tabulate(film, 1.5, n_mu=10, n_phi=8, rays=400, seed=2)
    p = t.probabilities
    assert np.allclose(p.sum(axis=1), 1.0) and (p >= 0).all()   # lossless: every photon leaves
    half = t.bins // 2
    # from inside the film, within 25.8 degrees of its axis (mu in [0.9, 1]), towards the prisms: mostly returned
    # (two total internal reflections at normal incidence; the bin's oblique part escapes through one face)
    near_normal = half + (t.n_mu - 1) * t.n_phi + np.arange(t.n_phi)
    assert p[near_normal, half:].sum(axis=1).mean() > 0.5
    back = tab.Table.from_arrays(t.arrays())
    assert back.n_mu == 10 and np.array_equal(back.cdf, t.cdf)
    with pytest.raises(ElementError, match="periodic"):
        tab.tabulate(prepare({**DOTS, "layout": {"type": "points", "uv_mm": [[1, 1], [2, 2]]}}), 1.5)
    with pytest.raises(ElementError, match="ior"):
        tab.tabulate(prepare(DOTS), 0.5)


def _plate(dots, table=None):
    s = Scene()
    v, t = box([0, 0, 0], [0.01, 0.01, 0.001])
    part = s.add_instance(s.add_geometry(v, t), np.eye(4))
    s.set_element(part, dots, facing=[0, 0, 1], table=table)
    s.commit()
    return s, part


def test_a_dotted_plate_transmits_the_same_flux_through_its_table_as_through_its_dots():
    dots = prepare(DOTS)
    rays = 1500
    table = tab.tabulate(dots, 1.49, rays=rays, seed=1)
    light = {"type": "collimated", "origin": [0.005, 0.005, 0.003], "direction": [0, 0, -1], "radius": 0.002,
             "illuminance_lx": 1000.0}
    below = ([-0.05, -0.05, -0.001], [0.1, 0.0, 0.0], [0.0, 0.1, 0.0], 1, 1)
    out = {}
    for name, t in (("exact", None), ("bsdf", table)):
        s, part = _plate(dots, t)
        r = Simulation(s, {part: PMMA}, [light]).grid(*below, max_photons=30_000, seed=5, estimator="forward")
        out[name] = (float(r.lux[0, 0]) * 0.01, float(r.stderr[0, 0]) * 0.01)
    flux = 1000.0 * math.pi * 0.002 ** 2
    # the table's resolution error on this quantity: how much the exact first crossing's transmitted share moves
    # over the beam's arriving bin (mu from 1 down to its edge), and the table row's own Monte Carlo error
    n_mu = table.n_mu
    u0, v0, su, sv, lu, lv = tab._patch(dots)
    s = tab._scene(dots, lu, lv, 10 * dots.h + 1.0)
    rng = np.random.default_rng(9)
    share = []
    for mu in (1.0, 1.0 - 1.0 / n_mu):
        k = 4000
        d = np.tile([math.sqrt(1 - mu * mu), 0.0, -mu], (k, 1))
        o = np.column_stack([u0 + rng.random(k) * su, v0 + rng.random(k) * sv, np.zeros(k)]) - (0.05 / mu) * d
        w, left = tab.trace(s, 1.49, o, d, rng)
        share.append(float(np.mean(left & (w[:, 2] < 0))))
    row = (n_mu - 1) * table.n_phi
    p = float(table.probabilities[row, table.bins // 2:].sum())
    resolution = abs(share[0] - share[1]) + 4 * math.sqrt(p * (1 - p) / rays) + 4 * math.sqrt(
        share[0] * (1 - share[0]) / 4000)
    (a, sa), (b, sb) = out["exact"], out["bsdf"]
    assert 0.5 * flux < a < flux
    assert abs(a - b) <= 4 * math.hypot(sa, sb) + resolution * flux, (a, b, sa, sb, resolution * flux)


def test_physics_left_out_measures_the_table_against_the_exact_geometry_on_a_copy_of_the_scene():
    """``physics_left_out: ["element_geometry"]`` on a plate used through its table: the difference is the exact
    dots' answer (the same query with the pilot's seed on the plate traced exactly) minus the table's, bit for bit;
    the scene queried keeps its table (the pilot ran on a copy: the same query answers the same again); on a plate
    without a table nothing runs and the difference is 0 ± 0. (How far the two models may differ: the test above.)"""
    from tracer.simulate import _pilot_seed

    dots = prepare(DOTS)
    table = tab.tabulate(dots, 1.49, rays=300, seed=1)
    light = {"type": "collimated", "origin": [0.005, 0.005, 0.003], "direction": [0, 0, -1], "radius": 0.002,
             "illuminance_lx": 1000.0}
    below = ([-0.05, -0.05, -0.001], [0.1, 0.0, 0.0], [0.0, 0.1, 0.0], 2, 1)
    ask = {"max_photons": 8_000, "seed": 5, "estimator": "forward"}
    s, part = _plate(dots, table)
    sim = Simulation(s, {part: PMMA}, [light])
    r = sim.grid(*below, **ask, physics_left_out=["element_geometry"])
    left = r.physics_left_out["element_geometry"]
    assert left["ran"] and left["photons"] > 0
    exact_scene, exact_part = _plate(dots)
    exact = Simulation(exact_scene, {exact_part: PMMA}, [light]).grid(*below, **{**ask, "seed": _pilot_seed(5, 0)})
    assert np.array_equal(left["difference"], exact.lux - r.lux)
    assert np.array_equal(left["stderr"], np.hypot(exact.stderr, r.stderr))
    assert s.tabulated_elements() == [part]
    again = sim.grid(*below, **ask)
    assert np.array_equal(again.lux, r.lux)
    plain, plain_part = _plate(dots)
    none = Simulation(plain, {plain_part: PMMA}, [light]).grid(*below, **ask, physics_left_out=["element_geometry"])
    assert not none.physics_left_out["element_geometry"]["ran"]
    assert np.all(none.physics_left_out["element_geometry"]["difference"] == 0)
