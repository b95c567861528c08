"""The relief kind's geometry (tracer.kinds.relief, tracer.elements): what a ray meets on a part whose face carries
an element with an inside, checked against the plain part and against closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.tracer.transport_scenes import box
from tracer.elements import ElementError, prepare
from tracer.scene import Scene

SIZE = (0.0625, 0.03125, 0.00390625)   # m (float32-exact): a 62.5 x 31.25 x 3.9 mm plate; its bottom face (normal -z)
# carries the element: its frame has u = x and v = n x u = -y, from the corner (0, SIZE[1], 0)


def dome(relief="bump", layout=None, radius=0.2, height=0.1):
    return prepare({"type": "microstructure", "feature": {"shape": "dome", "radius_mm": radius, "height_mm": height},
                    "relief": relief, "layout": layout or {"type": "grid", "pitch_mm": [0.5, 0.5]}})


def plate_scene():
    s = Scene()
    v, t = box([0, 0, 0], SIZE)
    i = s.add_instance(s.add_geometry(v, t), np.eye(4))
    s.commit()
    return s, i


def rays_from_inside(n, direction, seed=1):
    rng = np.random.default_rng(seed)
    o = np.column_stack([rng.uniform(0.001, SIZE[0] - 0.001, n), rng.uniform(0.001, SIZE[1] - 0.001, n),
                         np.full(n, SIZE[2] / 2)])
    d = np.tile(np.asarray(direction, float) / np.linalg.norm(direction), (n, 1))
    return o, d


@pytest.mark.parametrize("relief", ["bump", "pit"])
@pytest.mark.parametrize("layout", [{"type": "grid", "pitch_mm": [0.5, 0.5]}, {"type": "hex", "pitch_mm": 0.5},
                                    {"type": "density", "origin_mm": [0, 0], "size_mm": [50, 30],
                                     "fill": [[0.2, 0.9]], "pitch_mm": 0.5},
                                    {"type": "points", "uv_mm": [[1.0 + 1.5 * i + 0.3 * (j % 2), 1.0 + 1.1 * j]
                                                                 for i in range(30) for j in range(25)]}])
def test_a_ray_that_misses_every_feature_meets_the_plain_face_bit_for_bit(relief, layout):
    s, i = plate_scene()
    o, d = rays_from_inside(5000, [0.3, 0.1, -1.0])
    plain = s.intersect(o, d)
    s.set_element(i, dome(relief, layout), facing=[0, 0, -1])
    s.commit()
    with_element = s.intersect(o, d)
    feature = with_element.primitive < -1
    assert 0 < feature.sum() < len(o)
    same = ~feature
    for name in ("t", "instance", "primitive", "u", "v", "normal"):
        assert np.array_equal(getattr(plain, name)[same], getattr(with_element, name)[same]), name


@pytest.mark.parametrize("layout, coverage", [
    ({"type": "grid", "pitch_mm": [0.5, 0.4]}, math.pi * 0.2 ** 2 / (0.5 * 0.4)),
    ({"type": "hex", "pitch_mm": 0.5}, math.pi * 0.2 ** 2 / (0.5 * 0.5 * math.sqrt(3) / 2)),
])
def test_straight_down_the_share_of_rays_meeting_a_dome_is_its_layout_s_coverage(layout, coverage):
    """Rays leaving the plate straight down meet a feature exactly where they cross a base: the fraction is the
    area covered, a binomial proportion (4 sigma; the support's rim, where hex rows are cut, shrinks it by < 1 %)."""
    s, i = plate_scene()
    s.set_element(i, dome(layout=layout), facing=[0, 0, -1])
    s.commit()
    n = 40000
    o, d = rays_from_inside(n, [0, 0, -1], seed=7)
    hit = s.intersect(o, d)
    share = float((hit.primitive < -1).mean())
    sigma = math.sqrt(coverage * (1 - coverage) / n)
    assert abs(share - coverage) < 4 * sigma + (0.01 * coverage if layout["type"] == "hex" else 0.0), (share, coverage)


def test_a_dome_hit_lies_on_its_sphere_and_its_normal_is_the_sphere_s():
    s, i = plate_scene()
    s.set_element(i, dome(), facing=[0, 0, -1])
    s.commit()
    o, d = rays_from_inside(5000, [0.2, -0.3, -1.0])
    hit = s.intersect(o, d)
    f = hit.primitive < -1
    p = o[f] + hit.t[f, None] * d[f]
    rs = (0.2 ** 2 + 0.1 ** 2) / (2 * 0.1) * 1e-3
    cell = 0.5e-3
    centre = np.column_stack([(np.floor(p[:, 0] / cell) + 0.5) * cell,
                              SIZE[1] - (np.floor((SIZE[1] - p[:, 1]) / cell) + 0.5) * cell,
                              np.full(f.sum(), rs - 0.1e-3)])
    assert np.allclose(np.linalg.norm(p - centre, axis=1), rs, rtol=1e-9, atol=1e-12)
    assert (p[:, 2] <= 1e-12).all() and (p[:, 2] >= -0.1e-3 - 1e-12).all()
    assert np.allclose(hit.normal[f], (p - centre) / rs, atol=1e-6)


def test_a_pit_is_cut_into_the_part_and_its_normal_points_out_of_the_part():
    s, i = plate_scene()
    s.set_element(i, dome("pit"), facing=[0, 0, -1])
    s.commit()
    o, d = rays_from_inside(3000, [0.0, 0.0, -1.0])
    hit = s.intersect(o, d)
    f = hit.primitive < -1
    p = o[f] + hit.t[f, None] * d[f]
    assert (p[:, 2] >= 0).all() and (p[:, 2] <= 0.1e-3 + 1e-12).all()   # above the face: in the part
    assert (hit.normal[f, 2] < 0).all()   # the part's outward side, down into the pit


def test_taking_the_element_off_restores_the_part_and_a_move_rebuilds_nothing():
    s, i = plate_scene()
    o, d = rays_from_inside(2000, [0.1, 0.2, -1.0])
    plain = s.intersect(o, d)
    geometry = s.instance_geometry(i)
    s.set_element(i, dome(), facing=[0, 0, -1])
    s.commit()
    assert s.instance_geometry(i) == geometry
    m = np.eye(4)
    m[:3, 3] = [1.0, 2.0, 3.0]
    s.set_transform(i, m)
    stats = s.commit()
    assert stats.blas_built == 0
    moved = s.intersect(o + m[:3, 3], d)
    assert np.array_equal(moved.primitive < -1, s.intersect(o + m[:3, 3], d).primitive < -1)
    assert (moved.primitive < -1).any()
    s.set_transform(i, np.eye(4))
    s.set_element(i, None)
    s.commit()
    back = s.intersect(o, d)
    for name in ("t", "primitive", "u", "v", "normal"):
        assert np.array_equal(getattr(plain, name), getattr(back, name)), name


@pytest.mark.parametrize("body, words", [
    ({"type": "microstructure", "feature": {"shape": "dome", "radius_mm": 0.2, "height_mm": 0.1},
      "layout": {"type": "grid", "pitch_mm": [0.3, 0.5]}}, "layout.pitch_mm[0] (0.3 mm) is smaller than the feature"),
    ({"type": "microstructure", "feature": {"shape": "dome", "radius_mm": 0.2, "height_mm": 0.1},
      "layout": {"type": "density", "origin_mm": [0, 0], "size_mm": [5, 5], "fill": [[0.5, 1.2]]}},
     "layout.fill[0][1] = 1.2 is outside [0, 1]"),
    ({"type": "microstructure", "feature": {"shape": "dome", "radius_mm": 0.2, "height_mm": 0.3},
      "layout": {"type": "hex", "pitch_mm": 1}}, "must not exceed feature.radius_mm"),
    ({"type": "microstructure", "feature": {"shape": "cube", "size_mm": 1}, "layout": {"type": "hex", "pitch_mm": 1}},
     "feature.shape 'cube' is unknown"),
    ({"type": "microstructure", "feature": {"shape": "prism", "base_mm": 0.05, "apex_deg": 90},
      "layout": {"type": "hex", "pitch_mm": 1}}, "prisms are ridges"),
    ({"type": "microstructure", "feature": {"shape": "dome", "radius_mm": 0.2, "height_mm": 0.1},
      "layout": {"type": "points", "uv_mm": [[0, 0], [0.3, 0]]}}, "overlap"),
    ({"type": "microstructure", "feature": {"shape": "dome", "radius_mm": 0.2, "height_mm": 0.1},
      "layout": {"type": "grid", "pitch_mm": [1, 1]}, "colour": "red"}, "unknown field(s) ['colour']"),
    ({"type": "lens"}, "element type 'lens' is unknown"),
    ({"type": "microstructure", "feature": {"shape": "dome", "radius_mm": 0.2, "height_mm": 0.1},
      "layout": {"type": "grid", "pitch_mm": [1, 1]}, "material": {"type": "mirror"}}, "part's own material"),
])
def test_a_body_that_cannot_be_prepared_is_refused_naming_its_field(body, words):
    with pytest.raises(ElementError) as e:
        prepare(body)
    assert words in str(e.value)


def test_a_support_that_is_not_planar_or_not_selected_is_refused_and_the_scene_is_unchanged():
    s, i = plate_scene()
    o, d = rays_from_inside(500, [0.1, 0.2, -1.0])
    before = s.intersect(o, d)
    with pytest.raises(ElementError, match="no triangle"):
        s.set_element(i, dome(), facing=[1, 1, 1])
    with pytest.raises(ElementError, match="not planar"):   # the bottom and the top: two planes
        s.set_element(i, dome(), faces=[0, 1], face_ids=np.array([0, 0, 1, 1, 2, 2, 2, 2, 2, 2, 2, 2]))
    with pytest.raises(ElementError, match="facing"):
        s.set_element(i, dome())
    assert not s.dirty
    after = s.intersect(o, d)
    assert np.array_equal(before.t, after.t)


def test_the_same_body_gives_the_same_id_and_a_changed_one_another():
    a = dome()
    assert dome().id == a.id
    assert dome(radius=0.21).id != a.id
    assert a.features is None and a.nbytes < 100   # periodic: nothing per feature


def test_a_density_map_keeps_about_fill_of_its_sites_and_its_model_survives_a_file():
    fill = [[0.1, 0.5], [0.9, 0.3]]
    e = dome(layout={"type": "density", "origin_mm": [0, 0], "size_mm": [100, 100], "fill": fill, "seed": 4,
                     "pitch_mm": 0.5, "placement": "random"})   # blue noise: tests/tracer/elements/test_placement.py
    sites = 200 * 200
    expected = sites * float(np.mean(fill))
    assert abs(e.features - expected) < 4 * math.sqrt(sites * 0.25)
    assert e.nbytes <= sites // 8 + 8   # a bit per site, and an empty list of cells
    back = type(e).from_arrays(e.arrays())
    assert back.id == e.id and back.features == e.features and np.array_equal(back.bits, e.bits)


def test_a_point_list_is_the_same_body_as_ints_floats_or_an_array_and_takes_16_bytes_a_point():
    pts = [[1 + 2 * i, 1 + 2 * j] for i in range(30) for j in range(20)]
    a = dome(layout={"type": "points", "uv_mm": pts})
    b = dome(layout={"type": "points", "uv_mm": [[float(u), float(v)] for u, v in pts]})
    c = dome(layout={"type": "points", "uv_mm": np.array(pts, float)})
    assert a.id == b.id == c.id
    moved = [list(p) for p in pts]
    moved[7][1] += 1e-9
    assert dome(layout={"type": "points", "uv_mm": moved}).id != a.id
    assert a.features == 600 and a.nbytes <= 32 * a.features
    back = type(a).from_arrays(a.arrays())
    assert back.id == a.id and np.array_equal(back.uv, a.uv) and np.array_equal(back.items, a.items)
    # every listed point is found in its cell: bins and items are a counting sort of the points by cell
    cell = np.floor((a.uv.astype(np.float64) - np.array(a.origin)) / np.array(a.cell)).astype(int)
    flat = np.minimum(cell[:, 1], a.cells[1] - 1) * a.cells[0] + np.minimum(cell[:, 0], a.cells[0] - 1)
    for f in (0, 123, 599):
        assert f in a.items[a.bins[flat[f]]:a.bins[flat[f] + 1]]


@pytest.mark.parametrize("uv, words", [
    ([[0, 0], [1, 2, 3]], "layout.uv_mm must be a list of [u, v] pairs"),
    ([[0, 0], ["a", 1]], "layout.uv_mm must be a list of [u, v] pairs"),
    ([], "non-empty"),
    ("0,0", "layout.uv_mm must be a list of [u, v] pairs"),
    ([[0, 0], [float("nan"), 1]], "layout.uv_mm[1] is not finite"),
])
def test_a_bad_point_list_names_its_field(uv, words):
    with pytest.raises(ElementError) as e:
        dome(layout={"type": "points", "uv_mm": uv})
    assert words in str(e.value)


def test_a_density_lattice_is_drawn_band_by_band_as_one_draw_and_its_memory_stays_within_the_estimate(monkeypatch):
    """Issue 54, item 6: the kept sites are packed a band at a time (whole rows, or runs across rows where a row is
    longer than a band) and are bit for bit those of one draw over the whole lattice; tracemalloc's peak while
    preparing stays below `density_cost`'s bytes."""
    import tracemalloc

    from tracer.elements import microstructure as ms

    fill = [[0.1, 0.5, 0.2], [0.3, 0.9, 1.0]]

    def body(size, pitch):
        return {"type": "microstructure", "feature": {"shape": "dome", "radius_mm": pitch / 2, "height_mm": pitch / 4},
                "layout": {"type": "density", "origin_mm": [0, 0], "size_mm": size, "fill": fill, "seed": 3,
                           "pitch_mm": pitch, "placement": "random"}}

    def one_draw(nu, nv, pitch, size):
        f = np.asarray(fill)
        col = np.minimum(((np.arange(nu) + 0.5) * pitch / size[0] * f.shape[1]).astype(np.int64), f.shape[1] - 1)
        row = np.minimum(((np.arange(nv) + 0.5) * pitch / size[1] * f.shape[0]).astype(np.int64), f.shape[0] - 1)
        kept = np.random.default_rng(3).random((nv, nu)) < f[row][:, col]
        return np.packbits(kept.ravel(), bitorder="little"), int(kept.sum())

    for band_bytes, size in ((ms.BAND_BYTES, [20.3, 10.1]), (ms.BAND_SITE_BYTES * 3300, [20.3, 10.1]),
                             (ms.BAND_SITE_BYTES * 80, [20.3, 10.1])):   # one band; whole rows; runs across rows
        monkeypatch.setattr(ms, "BAND_BYTES", band_bytes)
        m = prepare(body(size, 0.1))
        bits, kept = one_draw(*m.cells, 0.1, size)
        assert m.cells == (202, 100) and np.array_equal(m.bits, bits) and m.features == kept
    monkeypatch.undo()
    tracemalloc.start()
    m = prepare(body([100.0, 20.0], 0.005))      # 8e7 sites: a byte each (before) is 80 MB beside the bits
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    sites = m.cells[0] * m.cells[1]
    assert sites > 7.9e7
    assert peak <= ms.density_cost(sites, "random")[0], (peak, ms.density_cost(sites, "random"))
