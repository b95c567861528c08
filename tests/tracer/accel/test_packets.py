"""A camera's rays through a scene of one mesh walk in packets of eight (tracer.accel.packets); each ray's answer
must still be the one-ray-at-a-time traversal's, bit for bit: under any instance transform (mirrors included),
on whole rays and on short segments, where the packet's directions share signs (a packet) and where they do not
(ray by ray), and where the packet's rays part ways deep in the tree (rows left to a few rays alone)."""

from __future__ import annotations

import numpy as np
import pytest

import tracer
from tests.tracer.accel.test_lanes import _one_by_one
from tracer.accel import packets, reference
from tracer.accel.lanes import is_coherent


def _wavy_grid(n: int) -> tuple[np.ndarray, np.ndarray]:
    """A height field of ``2 n^2`` triangles over [-1, 1]^2: small, edge-sharing triangles, as a tessellation."""
    x, y = np.meshgrid(np.linspace(-1, 1, n + 1), np.linspace(-1, 1, n + 1))
    z = 0.15 * np.sin(5 * x) * np.cos(4 * y)
    v = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    i = np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]
    a, b, c, d = i.ravel(), i.ravel() + 1, i.ravel() + n + 1, i.ravel() + n + 2
    return v, np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)])


def _camera(eye: np.ndarray, target: np.ndarray, w: int, fov: float) -> tuple[np.ndarray, np.ndarray]:
    """``w * w`` pinhole rays from ``eye`` towards ``target``, row after row."""
    fwd = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(fwd, [0.0, 1.0, 0.0] if abs(fwd[1]) < 0.9 else [1.0, 0.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    s = np.linspace(-np.tan(fov / 2), np.tan(fov / 2), w)
    x, y = np.meshgrid(s, s)
    d = fwd + x.reshape(-1, 1) * right + y.reshape(-1, 1) * up
    return np.tile(eye, (len(d), 1)), d


def _same_signs(d: np.ndarray, m: np.ndarray) -> np.ndarray:
    """For each packet of eight consecutive rays: do their object-space directions share signs on every axis?"""
    obj = d @ np.linalg.inv(m)[:3, :3].T
    s = (obj >= 0).reshape(-1, packets.WIDTH, 3)
    return np.all(s == s[:, :1], axis=(1, 2))


@pytest.mark.parametrize("mirror", [False, True])
def test_packets_equal_one_ray_at_a_time(mirror: bool) -> None:
    rng = np.random.default_rng(7 + mirror)
    m = reference.random_affine(rng, mirror=mirror, spread=0.5)
    scene = tracer.Scene()
    scene.add_instance(scene.add_geometry(*_wavy_grid(60)), m)
    scene.commit()
    centre = m[:3, 3]
    views = [_camera(centre + np.array([0.7, 0.9, 2.5]), centre, 128, 0.9),    # oblique: packets
             _camera(centre + m[:3, 2] * 3.0, centre, 128, 0.9)]              # along the normal: signs straddle
    for o, d in views:
        assert all(is_coherent(o, d, lo, lo + 256) for lo in range(0, len(o), 256))   # a camera's: packets
        k = len(o)
        t_max = np.where(rng.random(k) < 0.4, rng.uniform(0, 4, k), np.inf)
        hits = scene.intersect(o, d, t_max, threads=1)
        occ = scene.occluded(o, d, t_max, threads=1)
        t, inst, prim, uv, n, occ1 = _one_by_one(scene.arrays(), o, d, t_max)
        assert 0.1 < np.isfinite(t).mean() < 0.95   # hits and misses both
        assert np.array_equal(hits.t, t) and np.array_equal(hits.instance, inst)
        assert np.array_equal(hits.primitive, prim)
        assert np.array_equal(hits.u, uv[:, 0]) and np.array_equal(hits.v, uv[:, 1])
        assert np.array_equal(hits.normal, n)
        assert np.array_equal(occ, occ1)
    same = [_same_signs(d, m) for _, d in views]
    assert same[0].mean() > 0.9   # the oblique view walks in packets ...
    assert 0.0 < same[1].mean() < 1.0   # ... the other both in packets and ray by ray


def test_packets_rows_left_to_few_rays() -> None:
    """Neighbouring rays 0.45 degrees apart over triangles of 0.25 degrees part ways in the tree: the rows
    reached by few of them are walked by those rays alone, and the answers still agree."""
    scene = tracer.Scene()
    scene.add_instance(scene.add_geometry(*_wavy_grid(150)), np.eye(4))
    scene.commit()
    o, d = _camera(np.array([0.2, -0.3, 3.0]), np.zeros(3), 128, 1.0)
    t_max = np.full(len(o), np.inf)
    hits = scene.intersect(o, d, t_max, threads=1)
    t, inst, prim, uv, n, occ1 = _one_by_one(scene.arrays(), o, d, t_max)
    assert np.isfinite(t).mean() > 0.3
    assert np.array_equal(hits.t, t) and np.array_equal(hits.primitive, prim)
    assert np.array_equal(scene.occluded(o, d, t_max, threads=1), occ1)
