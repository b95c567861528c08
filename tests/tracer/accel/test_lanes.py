"""The batch queries keep several rays in flight per core (tracer.accel.lanes), or trace a camera's coherent
rays one after the other; each ray's answer must be the one-ray-at-a-time traversal's
(tracer.accel.traverse), whatever the batch size, the mix of rays that finish early and late, or a scene
with nothing to hit."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

import tracer
from tracer.accel import reference
from tracer.accel.lanes import LANES, is_coherent
from tracer.accel.traverse import intersect_any, intersect_closest


@njit(cache=True)
def _one_by_one(sa, o, d, t_max):
    k = o.shape[0]
    t = np.empty(k)
    inst = np.empty(k, np.int64)
    prim = np.empty(k, np.int64)
    uv = np.empty((k, 2))
    n = np.empty((k, 3))
    occ = np.empty(k, np.bool_)
    for i in range(k):
        t[i], inst[i], prim[i], uv[i, 0], uv[i, 1], n[i, 0], n[i, 1], n[i, 2] = intersect_closest(
            sa, o[i, 0], o[i, 1], o[i, 2], d[i, 0], d[i, 1], d[i, 2], t_max[i])
        occ[i] = intersect_any(sa, o[i, 0], o[i, 1], o[i, 2], d[i, 0], d[i, 1], d[i, 2], t_max[i])
    return t, inst, prim, uv, n, occ


def _scene(rng):
    scene = tracer.Scene()
    for _ in range(5):
        v, f = reference.random_mesh(rng, int(rng.integers(1, 80)))
        g = scene.add_geometry(v, f)
        for _ in range(4):
            scene.add_instance(g, reference.random_affine(rng))
    scene.add_disk_sensor((0, 0, 0), (0, 0, 1), 2.0)   # sensors: never hit by these queries
    scene.commit()
    return scene


def _camera(rng: np.random.Generator, k: int) -> tuple[np.ndarray, np.ndarray]:
    """``k`` rays from one point through a grid of pixels 0.01 rad apart, row after row, aimed at the
    scene."""
    eye = rng.uniform(-4, 4, 3)
    w = int(np.ceil(np.sqrt(k)))
    i = np.arange(k)
    fwd = -eye / np.linalg.norm(eye)
    right = np.cross(fwd, [0.3, 0.4, 0.866])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    x = ((i % w - w / 2) * 0.01)[:, None]
    y = ((i // w - w / 2) * 0.01)[:, None]
    return np.tile(eye, (k, 1)), (fwd + x * right + y * up) * rng.uniform(0.5, 2.0)


@pytest.mark.parametrize("k", [1, LANES - 1, LANES + 1, 300, 1000])
@pytest.mark.parametrize("rays", ["scattered", "point", "camera"])
def test_batch_equals_one_ray_at_a_time(k: int, rays: str) -> None:
    """Scattered rays, and a point source's, run in lanes; a camera's one after the other."""
    rng = np.random.default_rng(k)
    scene = _scene(rng)
    if rays == "camera":
        o, d = _camera(rng, k)
    else:
        o = np.tile(rng.uniform(-4, 4, 3), (k, 1)) if rays == "point" else rng.uniform(-4, 4, (k, 3))
        d = (rng.uniform(-2, 2, (k, 3)) - o) * rng.uniform(0.2, 5.0, (k, 1))
    assert is_coherent(o, d, 0, k) == (rays == "camera" or k == 1)
    t_max = np.where(rng.random(k) < 0.3, rng.uniform(0, 1, k), np.inf)
    hits = scene.intersect(o, d, t_max, threads=1)
    occ = scene.occluded(o, d, t_max, threads=1)
    t, inst, prim, uv, n, occ1 = _one_by_one(scene.arrays(), o, d, t_max)
    if k >= 300 and rays != "camera":   # hits and misses, on whole rays and on segments
        for seg in (t_max < np.inf, t_max == np.inf):
            assert 0.02 < np.isfinite(t[seg]).mean() < 0.98
    assert np.array_equal(hits.t, t) and np.array_equal(hits.instance, inst) and np.array_equal(hits.primitive, prim)
    assert np.array_equal(hits.u, uv[:, 0]) and np.array_equal(hits.v, uv[:, 1]) and np.array_equal(hits.normal, n)
    assert np.array_equal(occ, occ1)
    assert np.array_equal(occ, np.isfinite(t))   # any hit <=> a closest hit, on the same segment


def test_nothing_to_hit() -> None:
    for scene in (tracer.Scene(), tracer.Scene()):
        scene.commit()
        o = np.zeros((7, 3))
        d = np.tile([0.0, 0.0, 1.0], (7, 1))
        hits = scene.intersect(o, d)
        assert np.all(np.isinf(hits.t)) and np.all(hits.instance == -1) and np.all(hits.primitive == -1)
        assert not scene.occluded(o, d).any()
        assert len(scene.intersect(np.zeros((0, 3)), np.zeros((0, 3))).t) == 0


def test_camera_rays_hit_and_miss() -> None:
    """The camera batches above test hits and misses both (else their agreement would prove little)."""
    rng = np.random.default_rng(1000)
    scene = _scene(rng)
    o, d = _camera(rng, 1000)
    assert 0.05 < np.isfinite(scene.intersect(o, d).t).mean() < 0.95
