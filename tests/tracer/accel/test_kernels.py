"""The numba-level contract (docs/CONTRACTS.md) as light transport uses it: called from jitted code."""

from __future__ import annotations

import numpy as np
from numba import njit

import tracer
from tracer.accel import reference
from tracer.accel.spawn import offset_ray_origin
from tracer.accel.traverse import hit_point, intersect_any, intersect_closest, sensor_crossings, shading_normal


@njit(cache=True)
def _bounce(sa, o, d):
    """Closest hit, then a shadow ray back to the origin and the shading normal: transport's pattern."""
    k = o.shape[0]
    t_out = np.empty(k)
    inst_out = np.empty(k, np.int64)
    back = np.zeros(k, np.bool_)
    ns = np.zeros((k, 3))
    for i in range(k):
        t, inst, prim, u, v, nx, ny, nz = intersect_closest(sa, o[i, 0], o[i, 1], o[i, 2], d[i, 0], d[i, 1],
                                                            d[i, 2], np.inf)
        t_out[i] = t
        inst_out[i] = inst
        if inst >= 0:
            px, py, pz = hit_point(sa, inst, prim, u, v)
            qx, qy, qz = offset_ray_origin(px, py, pz, nx, ny, nz, -d[i, 0], -d[i, 1], -d[i, 2])
            back[i] = intersect_any(sa, qx, qy, qz, o[i, 0] - qx, o[i, 1] - qy, o[i, 2] - qz, 1.0)
            ns[i, 0], ns[i, 1], ns[i, 2] = shading_normal(sa, inst, prim, u, v)
    return t_out, inst_out, back, ns


def test_contract_functions_from_jitted_code(rng: np.random.Generator) -> None:
    v, f = reference.icosphere(3)
    scene = tracer.Scene()
    g = scene.add_geometry(v, f, normals=v)  # sphere: vertex normals = positions
    mats = [reference.random_affine(rng, spread=4.0, mirror=m) for m in (False, True)]
    for m in mats:
        scene.add_instance(g, m)
    scene.add_disk_sensor([0, 0, 0], [0, 0, 1], 100.0)  # crossed by everything, seen by nothing
    scene.commit()
    o = rng.normal(size=(300, 3)) * 8
    d = rng.uniform(-3, 3, (300, 3)) - o
    t, inst, back, ns = _bounce(scene.arrays(), o, d)
    ref = reference.intersect(scene, o, d)
    np.testing.assert_allclose(t, ref.t, rtol=1e-9)
    np.testing.assert_array_equal(inst, ref.instance)
    hit = inst >= 0
    assert hit.sum() > 30
    # the path back to the origin is clear when the origin is outside all spheres (which it is when
    # the ray hit from outside: normal against the ray)
    outside = np.einsum("ij,ij->i", ref.normal, d) < 0
    assert not back[hit & outside].any()
    # the interpolated vertex normal of a sphere is close to the geometric one (and unit)
    np.testing.assert_allclose(np.linalg.norm(ns[hit], axis=1), 1.0, rtol=1e-12)
    assert np.all(np.einsum("ij,ij->i", ns[hit], ref.normal[hit]) > 0.95)


def test_shading_normal_interpolates_and_transforms() -> None:
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    n = np.array([[0, 0, 1], [1, 0, 1], [0, 1, 1]], float)
    scene = tracer.Scene()
    with_n = scene.add_geometry(v, [[0, 1, 2]], n)
    without = scene.add_geometry(v, [[0, 1, 2]])
    m = np.diag([2.0, -1.0, 0.5, 1.0])  # non-uniform, mirrored
    a = scene.add_instance(with_n, m)
    b = scene.add_instance(without, m)
    scene.commit()
    sa = scene.arrays()
    u, w = 0.2, 0.3
    obj = (1 - u - w) * n[0] + u * n[1] + w * n[2]
    want = np.linalg.inv(m[:3, :3]).T @ obj
    np.testing.assert_allclose(shading_normal(sa, a, 0, u, w), want / np.linalg.norm(want), rtol=1e-6)
    geo = np.linalg.inv(m[:3, :3]).T @ np.array([0, 0, 1.0])
    np.testing.assert_allclose(shading_normal(sa, b, 0, u, w), geo / np.linalg.norm(geo), rtol=1e-12)
    np.testing.assert_allclose(hit_point(sa, b, 0, u, w), m[:3, :3] @ [u, w, 0], rtol=1e-12)


def test_sensor_crossings_ignore_solids() -> None:
    scene = tracer.Scene()
    g = scene.add_geometry([[-5, -5, 1], [5, -5, 1], [0, 5, 1]], [[0, 1, 2]])
    scene.add_instance(g, np.eye(4))
    s = scene.add_disk_sensor([0, 0, 0], [0, 0, 1], 1.0)
    scene.commit()
    out = [np.zeros(2, np.int64)] + [np.zeros(2) for _ in range(4)]
    assert sensor_crossings(scene.arrays(), 0.0, 0.0, 5.0, 0.0, 0.0, -1.0, 10.0, *out) == 1
    assert out[0][0] == s and out[4][0] == 1.0
