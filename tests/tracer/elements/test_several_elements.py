"""Several elements on one part (issue 53: "dots underneath and prisms on top of the same guide cannot both be
modelled"): each on its own support, rays meet each as they meet it alone, light through both as through the same
dots meshed under the same prisms, and the refusals that change nothing."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.tracer.elements.meshed_relief import domed_plate
from tests.tracer.transport_scenes import box
from tracer.elements import ElementError, prepare
from tracer.elements import features as fx
from tracer.elements.checks import SupportTaken
from tracer.kinds import mesh
from tracer.optics.surfaces.dispatch import feature_surface
from tracer.scene import Scene
from tracer.simulate import Simulation

SIZE, THICK = 4e-3, 1e-3   # m
DOMES = {"type": "microstructure", "layout": {"type": "grid", "pitch_mm": [0.2, 0.2]},
         "feature": {"shape": "dome", "radius_mm": 0.08, "height_mm": 0.04}}
PRISMS = {"type": "microstructure", "feature": {"shape": "prism", "base_mm": 0.05, "apex_deg": 100},
          "layout": {"type": "grid", "pitch_mm": [0.05, 0.05]}}
BLACK_DOTS = {"type": "microstructure", "material": {"type": "black"},
              "layout": {"type": "grid", "pitch_mm": [0.5, 0.5]}, "feature": {"shape": "pyramid", "base_mm": 0.3,
                                                                               "height_mm": 0.02}}


def _plate(*elements):
    """A SIZE x SIZE x THICK plate carrying `elements`: (body, facing, key) each."""
    s = Scene()
    v, t = box([0, 0, 0], [SIZE, SIZE, THICK])
    part = s.add_instance(s.add_geometry(v, t), np.eye(4))
    for body, facing, key in elements:
        s.set_element(part, prepare(body), facing=facing, mm_per_unit=1000.0, key=key)
    s.commit()
    return s, part


def _rays(n, z, dz, seed):
    rng = np.random.default_rng(seed)
    o = np.column_stack([rng.uniform(0.1, 0.9, n) * SIZE, rng.uniform(0.1, 0.9, n) * SIZE, np.full(n, z)])
    d = np.column_stack([rng.normal(0, 0.3, n), rng.normal(0, 0.3, n), np.full(n, dz)])
    return o, d / np.linalg.norm(d, axis=1, keepdims=True)


def _same_first_hit(both, alone, o, d, k):
    """`both`'s first hits equal `alone`'s: the same distances, normals and points; a feature hit names row `k`."""
    a, b = both.intersect(o, d), alone.intersect(o, d)
    np.testing.assert_array_equal(a.instance, b.instance)   # the steepest rays pass the plate's edge
    assert (a.instance == 0).mean() > 0.9
    np.testing.assert_array_equal(a.t, b.t)
    np.testing.assert_array_equal(a.normal, b.normal)
    on_feature = b.primitive < -1
    assert on_feature.any()
    np.testing.assert_array_equal(a.primitive[~on_feature], b.primitive[~on_feature])   # the part's triangle (or -1)
    code_a, code_b = -2 - a.primitive[on_feature], -2 - b.primitive[on_feature]
    assert (code_a % fx.PART_ROWS == k).all() and (code_a // fx.PART_ROWS == code_b // fx.PART_ROWS).all()


def test_each_of_two_elements_on_one_part_meets_rays_as_it_does_alone():
    """Domes underneath and prisms on top of one plate: rays from above meet the prisms and from below the domes
    exactly as on a plate carrying that element alone (distances and normals bit-equal), each feature hit naming its
    element's row."""
    both, _ = _plate((DOMES, [0, 0, -1], "dots"), (PRISMS, [0, 0, 1], "prisms"))
    assert both.elements_on(0) == ["dots", "prisms"]
    _same_first_hit(both, _plate((PRISMS, [0, 0, 1], 0))[0], *_rays(4000, THICK + 1e-3, -1.0, 1), 1)
    _same_first_hit(both, _plate((DOMES, [0, 0, -1], 0))[0], *_rays(4000, -1e-3, 1.0, 2), 0)


def test_a_feature_hit_takes_the_surface_of_its_own_element():
    """Black printed dots underneath, clear domes (the part's material) on top: a hit on a dot reads black, a hit on
    a dome the part's own surface; reading the part's first element for both would make the dots clear."""
    s, part = _plate((DOMES, [0, 0, 1], "domes"), (BLACK_DOTS, [0, 0, -1], "dots"))
    a = s.arrays()
    for z, dz, want in ((THICK + 1e-3, -1.0, fx.MAT_PART), (-1e-3, 1.0, fx.MAT_BLACK)):
        o, d = _rays(2000, z, dz, 3)
        h = s.intersect(o, d)
        features = h.primitive[h.primitive < -1]
        assert len(features) > 100
        assert {feature_surface(a, part, int(p))[0] for p in features} == {want}


def test_light_through_dots_underneath_and_prisms_on_top_is_that_of_the_dots_meshed_under_the_same_prisms():
    """A PMMA plate, 20 x 20 domes on its bottom and a 100-degree prism film on its top, lit at 30 degrees from
    above: the illuminance map below it with both as elements of the one part, and with the domes meshed explicitly
    (~250k triangles) under the prisms as the meshed part's only element, agree cell by cell within 4 combined sigma
    (plus the mesh's own facetting, 0.5 % of the mean)."""
    n, pitch, radius, height = 20, 0.2e-3, 0.08e-3, 0.04e-3
    size = n * pitch
    prisms = prepare(PRISMS)
    meshed = Scene()
    v, t = domed_plate(n, pitch, radius, height, THICK)
    meshed_part = meshed.add_instance(meshed.add_geometry(v, t), np.eye(4))
    meshed.set_element(meshed_part, prisms, facing=[0, 0, 1])
    meshed.commit()
    both, both_part = _plate((DOMES, [0, 0, -1], "dots"), (PRISMS, [0, 0, 1], "prisms"))
    s30, c30 = math.sin(math.radians(30)), math.cos(math.radians(30))
    light = {"type": "collimated", "origin": [size / 2 - 2e-3 * s30, size / 2, THICK + 2e-3],
             "direction": [s30, 0, -c30], "radius": 1.2e-3, "illuminance_lx": 1000.0}
    floor = ([-2e-3, -2e-3, -1e-3], [size + 4e-3, 0, 0], [0, size + 4e-3, 0], 4, 4)
    pmma = {"type": "dielectric", "ior": 1.49}
    a = Simulation(meshed, {meshed_part: pmma}, [light]).grid(*floor, max_photons=300_000, seed=5,
                                                                 estimator="forward")
    b = Simulation(both, {both_part: pmma}, [light]).grid(*floor, max_photons=300_000, seed=5, estimator="forward")
    lit = a.lux > 0.05 * a.lux.max()
    assert lit.sum() >= 4
    sigma = np.sqrt(a.stderr ** 2 + b.stderr ** 2)
    z = np.abs(a.lux - b.lux)[lit] / (4 * sigma[lit] + 0.005 * a.lux.mean())
    assert (z < 1).all(), (a.lux, b.lux, sigma)


def test_a_support_another_element_holds_is_refused_naming_it_and_nothing_changes():
    s, part = _plate((DOMES, [0, 0, -1], "dots"))
    before = s.arrays()
    with pytest.raises(SupportTaken, match="'dots'") as caught:
        s.set_element(part, prepare(PRISMS), facing=[0, 0, -1], key="prisms")
    assert caught.value.key == "dots"
    assert s.elements_on(part) == ["dots"]
    s.commit()
    after = s.arrays()
    np.testing.assert_array_equal(after.el_i, before.el_i)
    np.testing.assert_array_equal(after.el_prim, before.el_prim)


def test_a_part_carries_at_most_part_rows_elements():
    s = Scene()
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float) * 1e-3
    tris, verts = [], []
    for k in range(fx.PART_ROWS + 1):   # squares side by side, each tilted to face a direction of its own
        a = math.radians(5.0 * k)
        rot = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
        verts.append((v @ rot.T) + [2e-3 * k, 0, 0])
        tris.append(np.array([[0, 1, 2], [0, 2, 3]]) + 4 * k)
    part = s.add_instance(s.add_geometry(np.vstack(verts), np.vstack(tris)), np.eye(4))
    dots = prepare({**DOMES, "layout": {"type": "grid", "pitch_mm": [0.5, 0.5]}})
    for k in range(fx.PART_ROWS):
        a = math.radians(5.0 * k)
        s.set_element(part, dots, facing=[0, -math.sin(a), math.cos(a)], key=k)
    a = math.radians(5.0 * fx.PART_ROWS)
    with pytest.raises(ElementError, match=f"at most {fx.PART_ROWS} elements"):
        s.set_element(part, dots, facing=[0, -math.sin(a), math.cos(a)], key="one more")
    assert s.elements_on(part) == list(range(fx.PART_ROWS))


def test_taking_one_element_off_keeps_the_other_and_taking_both_off_restores_the_part():
    s, part = _plate((DOMES, [0, 0, -1], "dots"), (PRISMS, [0, 0, 1], "prisms"))
    full = s.instance_geometry(part)
    s.set_element(part, None, key="dots")
    s.commit()
    alone, _ = _plate((PRISMS, [0, 0, 1], "prisms"))
    o, d = _rays(2000, THICK + 1e-3, -1.0, 4)
    np.testing.assert_array_equal(s.intersect(o, d).t, alone.intersect(o, d).t)
    o, _ = _rays(2000, -1e-3, 1.0, 5)
    up = np.tile([0.0, 0.0, 1.0], (len(o), 1))
    np.testing.assert_allclose(s.intersect(o, up).t, 1e-3, rtol=1e-12)   # the bottom is flat again
    assert s.elements_on(part) == ["prisms"] and s.element_of(part, "dots") is None
    s.set_element(part, None, key="prisms")
    s.commit()
    assert int(s.arrays().inst_kind[part]) == mesh.KIND and s.instance_geometry(part) == full
    assert s.elements_on(part) == []
