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


def _transmits_alike(dots, table, rays, centre, radius, photons, least):
    """A normal collimated beam of 1000 lx and `radius` m on the plate at `centre` (x, y m): the flux it sends into a
    cell under the plate through the exact dots (more than `least` of the beam's) and through `table` (of `rays` a
    bin) agree within 4 combined σ plus the table's resolution error (`_resolution`)."""
    light = {"type": "collimated", "origin": [*centre, 0.003], "direction": [0, 0, -1], "radius": radius,
             "illuminance_lx": 1000.0}
    below = ([-0.05, -0.05, -0.001], [0.1, 0.0, 0.0], [0.0, 0.1, 0.0], 1, 1)
    out = {}
    for name, t in (("exact", None), ("bsdf", table)):
        s, part = _plate(dots, t)
        r = Simulation(s, {part: PMMA}, [light]).grid(*below, max_photons=photons, seed=5, estimator="forward")
        out[name] = (float(r.lux[0, 0]) * 0.01, float(r.stderr[0, 0]) * 0.01)
    flux = 1000.0 * math.pi * radius ** 2
    (a, sa), (b, sb) = out["exact"], out["bsdf"]
    resolution = _resolution(dots, table, rays)
    assert least * flux < a < flux
    assert abs(a - b) <= 4 * math.hypot(sa, sb) + resolution * flux, (a, b, sa, sb, resolution * flux)


def test_a_dotted_plate_transmits_the_same_flux_through_its_table_as_through_its_dots():
    dots = prepare(DOTS)
    rays = 1500
    table = tab.tabulate(dots, 1.49, rays=rays, seed=1)
    _transmits_alike(dots, table, rays, (0.005, 0.005), 0.002, 30_000, least=0.5)


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


def _density(fill, material=None, height=0.04):
    body = {"type": "microstructure", "feature": {"shape": "dome", "radius_mm": 0.08, "height_mm": height},
            "layout": {"type": "density", "origin_mm": [0, 0], "size_mm": [10, 10], "fill": fill, "pitch_mm": 0.2}}
    return prepare({**body, "material": material} if material else body)


def _resolution(e, table, rays):
    """The table's resolution error on a normal beam's transmitted share, the worst over a density map's levels (a
    periodic layout's one table): the exact share's move over the beam's arriving bin (mu from 1 down to its edge)
    on each level's patch, and the Monte Carlo errors of the level's row and of those shares."""
    u0, v0, su, sv, lu, lv = tab._patch(e)
    rng = np.random.default_rng(9)
    worst = 0.0
    nb = table.bins
    for level, (_, patch) in enumerate(tab._levels(e, lu, lv)):
        s = tab._scene(patch, lu, lv, 10 * e.h + 1.0)
        share = []
        for mu in (1.0, 1.0 - 1.0 / table.n_mu):
            k = 4000
            d = np.tile([math.sqrt(1 - mu * mu), 0.0, -mu], (k, 1))
            o = np.column_stack([u0 + rng.random(k) * su, v0 + rng.random(k) * sv, np.zeros(k)]) - (0.05 / mu) * d
            w, left = tab.trace(s, table.ior, o, d, rng, (e.material, e.reflectance))
            share.append(float(np.mean(left & (w[:, 2] < 0))))
        row = level * nb + (table.n_mu - 1) * table.n_phi
        p = float(table.probabilities[row, nb // 2:].sum())
        worst = max(worst, abs(share[0] - share[1]) + 4 * math.sqrt(p * (1 - p) / rays)
                    + 4 * math.sqrt(share[0] * (1 - share[0]) / 4000))
    return worst


@pytest.mark.parametrize("material", [None, {"type": "lambertian", "reflectance": 0.5}], ids=["domes", "printed"])
def test_a_density_map_s_tables_by_fill_level_transmit_what_its_dots_transmit(material):
    """A plate whose dots follow a 2 x 2 map (fills 0.1, 0.9, 0.6, 0.3: none a level but 0.9's neighbours) is
    tabulated as five tables, fill 0 to 1; the photons meeting the support scatter by the two levels around the fill
    where they land. A normal beam on one quadrant transmits the same flux through the tables as through the
    placed dots, within 4 combined sigma plus the tables' resolution error (the test above's, the worst level).
    Printed dots (Lambertian, reflectance 0.5, their own surface) absorb half of what meets them: their table's rows
    hold less than 1, and the plate still transmits what its dots let through."""
    dots = _density([[0.1, 0.9], [0.6, 0.3]], material, height=0.04 if material is None else 0.005)
    rays = 1500
    table = tab.tabulate(dots, 1.49, rays=rays, seed=1)
    assert table.levels == tab.LEVELS and table.cdf.shape == (tab.LEVELS * table.bins, table.bins)
    assert {side: "fill" in err for side, err in table.error.items()} == {"air": True, "solid": True}
    back = tab.Table.from_arrays(table.arrays())
    assert back.levels == tab.LEVELS and back.error == table.error and np.array_equal(back.cdf, table.cdf)
    sums = table.probabilities.sum(axis=1).reshape(tab.LEVELS, table.bins)
    assert np.allclose(sums[0], 1.0)   # fill 0: a plain face, lossless
    if material is None:   # lossless but for a rare photon still inside after MAX_BOUNCES (full fill: 1 in 1500)
        assert sums.min() > 0.998 and sums.mean() > 0.9999
    else:   # the fuller the face, the more its dots absorb
        assert np.all(np.diff(sums.mean(axis=1)) < 0) and sums[-1].mean() < 0.9
    # a normal beam on the quadrant u > 5, v < 5 mm (the map's row 0, column 1: fill 0.9; the fill read at u, v the
    # other way round would be 0.6's)
    _transmits_alike(dots, table, rays, (0.0075, 0.0025), 0.0022, 60_000, least=0.3)


def test_the_solid_side_s_bins_split_at_the_critical_angle_and_the_transport_bins_as_the_table_does():
    """The solid side's |cos θ| edges hold the critical angle's |cos| sqrt(1 − 1/n²) (n = 1.49: 0.7416), ``split``
    bins below it, the air side's stay uniform; the transport's bin of a direction (`dispatch.mu_bin`) and its
    direction drawn in a bin (`dispatch.mu_in_bin`) are the table's (`bin_of`, `sample_in_bin`)."""
    from tracer.optics.surfaces.dispatch import mu_bin, mu_in_bin

    n_mu, ior = 6, 1.49
    k = tab.split_for(n_mu, ior)
    solid = tab.mu_edges(n_mu, ior, k)
    c = math.sqrt(1 - 1 / ior ** 2)
    assert k == 4 and solid[k] == pytest.approx(c) and solid[0] == 0.0 and solid[-1] == 1.0
    assert np.all(np.diff(solid) > 0) and np.allclose(tab.mu_edges(n_mu, ior, 0), np.linspace(0, 1, 7))
    assert tab.split_for(n_mu, 1.0) == 0
    rng = np.random.default_rng(3)
    mu = rng.random(2000)
    w = np.column_stack([np.sqrt(1 - mu * mu), np.zeros_like(mu), -mu])   # into the solid: side 1
    bins = tab.bin_of(w, n_mu, 1, solid)
    assert np.array_equal(bins - n_mu, [mu_bin(m, n_mu, k, c) for m in mu])
    u = rng.random(2000)
    drawn = tab.sample_in_bin(bins, n_mu, 1, u, np.zeros_like(u), solid)
    assert np.allclose(-drawn[:, 2], [mu_in_bin(b - n_mu, x, n_mu, k, c) for b, x in zip(bins, u, strict=True)])
    assert np.all(tab.bin_of(drawn, n_mu, 1, solid) == bins)   # a direction drawn in a bin is binned back there


@pytest.mark.parametrize("deg", [44.0, 46.0])
def test_light_trapped_by_total_internal_reflection_leaves_only_through_the_dots_in_the_table_too(deg):
    """From inside the plate at 44° and 46° from the normal (beyond the critical angle, 42.2° for n = 1.49) the face
    reflects totally between the dots, and only what the dots let out leaves (traced exactly: about a quarter). The
    table reads the same within 4σ; with the solid side's bins uniform (``split=False``, as before 2026-12-08) the
    bin holding these directions reached into the escape cone, and the table let 0.46 out, about 1.8 times too
    much: a light guide's trapped light leaked between its dots."""
    dots = prepare(DOTS)
    u0, v0, su, sv, lu, lv = tab._patch(dots)
    s = tab._scene(dots, lu, lv, 10 * dots.h + 1.0)
    rng = np.random.default_rng(4)
    mu, k = math.cos(math.radians(deg)), 8000
    came_from = np.tile([math.sqrt(1 - mu * mu), 0.0, -mu], (k, 1))   # below the face, inside the solid
    d = -came_from
    start = np.column_stack([u0 + rng.random(k) * su, v0 + rng.random(k) * sv, np.zeros(k)])
    o = start + (-1e-4 / d[:, 2])[:, None] * d   # just under the face
    out, left = tab.trace(s, 1.49, o, d, rng)
    exact = float(np.mean(left & (out[:, 2] > 0)))
    rays = 1500
    shares = {}
    for split in (True, False):
        t = tab.tabulate(dots, 1.49, rays=rays, seed=1, split=split)
        row = tab.bin_of(came_from[:1], t.n_mu, t.n_phi, t.edges(1) if t.split else None)[0]
        shares[split] = float(t.probabilities[row, :t.bins // 2].sum())   # into the air: side 0
    sigma = math.sqrt(exact * (1 - exact) / k + shares[True] * (1 - shares[True]) / rays)
    assert 0.15 < exact < 0.4 and abs(shares[True] - exact) <= 4 * sigma, (exact, shares, sigma)
    assert shares[False] - exact > 0.15, (exact, shares)
