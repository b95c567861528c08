"""Sensor bottom levels (disk, rect): crossings with t, (u, v) and the signed cosine; closest-hit and
any-hit queries do not see sensors."""

from __future__ import annotations

import numpy as np

import tracer
from tracer.accel.traverse import sensor_crossings


def _cross(scene: tracer.Scene, o, d, t_max=np.inf, cap=8):
    out = (np.zeros(cap, np.int64), np.zeros(cap), np.zeros(cap), np.zeros(cap), np.zeros(cap))
    n = sensor_crossings(scene.arrays(), *map(float, o), *map(float, d), float(t_max), *out)
    return [tuple(a[q] for a in out) for q in range(n)]


def test_disk_crossing_point_and_cosine(rng: np.random.Generator) -> None:
    scene = tracer.Scene()
    c = np.array([1.0, 2.0, 3.0])
    n = np.array([1.0, -2.0, 0.5])
    n_unit = n / np.linalg.norm(n)
    r = 0.25
    i = scene.add_disk_sensor(c, n, r)
    scene.commit()
    for _ in range(200):
        p = c + rng.normal(size=3) * 0.2
        p -= np.dot(p - c, n_unit) * n_unit  # a point in the disk's plane
        d = rng.normal(size=3) * rng.uniform(0.5, 3)
        o = p - 2.0 * d
        hits = _cross(scene, o, d)
        inside = np.linalg.norm(p - c) < r * (1 - 1e-9)
        outside = np.linalg.norm(p - c) > r * (1 + 1e-9)
        if outside:
            assert hits == []
            continue
        if not inside:
            continue
        assert len(hits) == 1
        inst, t, u, v, cos = hits[0]
        assert inst == i
        np.testing.assert_allclose(t, 2.0, rtol=1e-12)
        np.testing.assert_allclose(np.hypot(u, v), np.linalg.norm(p - c) / r, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(cos, -np.dot(d, n_unit) / np.linalg.norm(d), rtol=1e-9, atol=1e-15)


def test_rect_crossing_coordinates_and_sides(rng: np.random.Generator) -> None:
    scene = tracer.Scene()
    origin = np.array([0.5, -1.0, 2.0])
    u_edge = np.array([2.0, 0.0, 0.5])
    v_edge = np.array([0.0, 1.0, 1.0])  # not orthogonal to u: a parallelogram
    i = scene.add_rect_sensor(origin, u_edge, v_edge)
    scene.commit()
    front = np.cross(u_edge, v_edge)
    for _ in range(100):
        a, b = rng.uniform(0.01, 0.99, 2)
        p = origin + a * u_edge + b * v_edge
        for side in (1.0, -1.0):
            d = -side * front + rng.normal(size=3) * 0.3
            (inst, t, u, v, cos), = _cross(scene, p - 0.5 * d, d)
            assert inst == i
            np.testing.assert_allclose([t, u, v], [0.5, a, b], rtol=1e-9)
            assert np.sign(cos) == side  # > 0: arriving on the front (u x v) side
    assert _cross(scene, origin - u_edge * 0.1 + [0, 0, 5.0], [0, 0, -1.0]) == []


def test_sensors_are_invisible_to_queries_and_sorted_by_t() -> None:
    scene = tracer.Scene()
    ids = [scene.add_disk_sensor([0, 0, z], [0, 0, 1], 1.0) for z in (3.0, 1.0, 2.0, 4.0)]
    scene.commit()
    o = np.array([[0.1, 0.1, 10.0]])
    d = np.array([[0.0, 0.0, -1.0]])
    assert scene.intersect(o, d).instance[0] == -1
    assert not scene.occluded(o, d)[0]
    hits = _cross(scene, o[0], d[0])
    assert [h[0] for h in hits] == [ids[3], ids[0], ids[2], ids[1]]
    np.testing.assert_allclose([h[1] for h in hits], [6, 7, 8, 9])
    assert all(h[4] > 0 for h in hits)
    # capacity: the nearest ones are kept; the segment is (0, t_max)
    assert [h[0] for h in _cross(scene, o[0], d[0], cap=2)] == [ids[3], ids[0]]
    assert [h[0] for h in _cross(scene, o[0], d[0], t_max=7.5)] == [ids[3], ids[0]]
    assert _cross(scene, o[0], d[0], cap=0) == []


def test_sensor_moves_and_removal_with_a_mesh_present() -> None:
    scene = tracer.Scene()
    g = scene.add_geometry([[-5, -5, 0], [5, -5, 0], [0, 5, 0]], [[0, 1, 2]])
    floor = scene.add_instance(g, np.eye(4))
    s = scene.add_rect_sensor([-1, -1, 1.0], [2, 0, 0], [0, 2, 0])
    scene.commit()
    o, d = np.array([0.0, 0.0, 5.0]), np.array([0.0, 0.0, -1.0])
    assert scene.intersect(o[None], d[None]).instance[0] == floor
    assert [h[0] for h in _cross(scene, o, d)] == [s]
    m = scene.instance_transform(s)
    m[2, 3] = -1.0  # below the floor: still crossed by the segment, which is not stopped by sensors
    scene.set_transform(s, m)
    scene.commit()
    (_, t, _, _, _), = _cross(scene, o, d)
    assert t == 6.0
    assert scene.instance_geometry(s) == "sensor:rect" and scene.is_sensor(s)
    scene.remove_instance(s)
    scene.commit()
    assert _cross(scene, o, d) == []
    assert scene.instances() == [floor]
