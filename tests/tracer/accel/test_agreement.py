"""The fast two-level tracer agrees with the brute-force world-space reference (tracer.accel.reference).

Random scenes: several random meshes, each instanced several times with random affine maps
(rotations, non-uniform scale, mirroring). Per ray: same t (relative 1e-9), and the same
instance/primitive/barycentrics/normal unless the reference itself has a tie at that t (a ray through
a shared edge may legally report either triangle).
"""

from __future__ import annotations

import numpy as np
import pytest

import tracer
from tracer.accel import reference


def _random_scene(rng: np.random.Generator, n_geoms: int = 4, n_inst: int = 3, normals: bool = False):
    scene = tracer.Scene()
    for _ in range(n_geoms):
        v, f = reference.random_mesh(rng, int(rng.integers(1, 60)))
        n = rng.normal(size=v.shape) if normals else None
        g = scene.add_geometry(v, f, n)
        for _ in range(n_inst):
            scene.add_instance(g, reference.random_affine(rng))
    return scene


def _random_rays(rng: np.random.Generator, k: int, spread: float = 4.0):
    o = rng.uniform(-spread, spread, (k, 3))
    target = rng.uniform(-spread / 2, spread / 2, (k, 3))
    d = (target - o) * rng.uniform(0.2, 5.0, (k, 1))  # non-unit directions: t in units of |d|
    return o, d


def assert_same_hits(scene, ours, ref, o, d) -> None:
    both = np.isfinite(ref.t)
    assert np.array_equal(np.isfinite(ours.t), both), "hit/miss differs"
    np.testing.assert_allclose(ours.t[both], ref.t[both], rtol=1e-9)
    same = (ours.instance == ref.instance) & (ours.primitive == ref.primitive)
    for r in np.flatnonzero(both & ~same):
        hits = reference.all_hits(scene, o[r], d[r])
        tied = {(i, p) for t, i, p in hits if abs(t - ref.t[r]) <= 1e-9 * ref.t[r]}
        assert (int(ours.instance[r]), int(ours.primitive[r])) in tied, f"ray {r}: not a tie"
    s = both & same
    np.testing.assert_allclose(ours.u[s], ref.u[s], atol=1e-7)
    np.testing.assert_allclose(ours.v[s], ref.v[s], atol=1e-7)
    np.testing.assert_allclose(ours.normal[s], ref.normal[s], atol=1e-7)
    assert np.all(ours.instance[~both] == -1) and np.all(ours.primitive[~both] == -1)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_closest_hit_matches_brute_force(seed: int) -> None:
    rng = np.random.default_rng(seed)
    scene = _random_scene(rng)
    scene.commit()
    o, d = _random_rays(rng, 400)
    ours = scene.intersect(o, d)
    ref = reference.intersect(scene, o, d)
    assert np.isfinite(ref.t).sum() > 50  # the test means something
    assert_same_hits(scene, ours, ref, o, d)


def test_mirrored_and_scaled_instances_are_all_exercised(rng: np.random.Generator) -> None:
    scene = tracer.Scene()
    v, f = reference.icosphere(2)
    g = scene.add_geometry(v, f)
    mats = [reference.random_affine(rng, mirror=m, anisotropy=5.0) for m in (True, False, True, False)]
    for m in mats:
        scene.add_instance(g, m)
    scene.commit()
    o, d = _random_rays(rng, 600)
    ours = scene.intersect(o, d)
    ref = reference.intersect(scene, o, d)
    assert set(np.unique(ref.instance[ref.instance >= 0])) == {0, 1, 2, 3}
    assert_same_hits(scene, ours, ref, o, d)
    # a closed mesh wound outward: outside rays see outward normals, also on mirrored instances
    hit = np.isfinite(ours.t)
    centre = np.array([mats[i][:3, 3] for i in ours.instance[hit]])
    p = o[hit] + ours.t[hit, None] * d[hit]
    outside = np.array([np.linalg.norm(np.linalg.solve(mats[i][:3, :3], o[r] - mats[i][:3, 3])) > 1.0
                        for r, i in zip(np.flatnonzero(hit), ours.instance[hit], strict=True)])
    outward = np.einsum("ij,ij->i", ours.normal[hit], p - centre)
    assert np.all(outward[outside] > 0)


@pytest.mark.parametrize("seed", [4, 5])
def test_occluded_matches_brute_force(seed: int) -> None:
    rng = np.random.default_rng(seed)
    scene = _random_scene(rng)
    scene.commit()
    o, d = _random_rays(rng, 300)
    ref = reference.intersect(scene, o, d)
    t_max = rng.uniform(0.0, 2.0, len(o))
    blocked = scene.occluded(o, d, t_max)
    clear_margin = np.abs(ref.t - t_max) > 1e-9 * np.maximum(1, t_max)
    assert np.array_equal(blocked[clear_margin], (ref.t < t_max)[clear_margin])
    assert blocked.any() and not blocked.all()


def test_t_max_limits_closest_hit(rng: np.random.Generator) -> None:
    scene = _random_scene(rng)
    scene.commit()
    o, d = _random_rays(rng, 200)
    full = scene.intersect(o, d)
    limit = np.where(np.isfinite(full.t), full.t * 0.5, 1.0)
    half = scene.intersect(o, d, limit)
    assert np.all((half.instance == -1) | (half.t < limit))
    assert np.all(half.instance[np.isfinite(full.t)] == -1)  # nothing nearer than the closest hit
    cut = scene.intersect(o, d, np.where(np.isfinite(full.t), full.t * (1 + 1e-6), 1.0))
    np.testing.assert_array_equal(cut.instance, np.where(np.isfinite(full.t), full.instance, cut.instance))


def test_one_thread_equals_all_threads(rng: np.random.Generator) -> None:
    scene = _random_scene(rng)
    scene.commit()
    o, d = _random_rays(rng, 500)
    a = scene.intersect(o, d, threads=1)
    b = scene.intersect(o, d)
    for f in ("t", "instance", "primitive", "u", "v", "normal"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f))
    np.testing.assert_array_equal(scene.occluded(o, d, 1.0, threads=1), scene.occluded(o, d, 1.0))


def test_large_meshes_deep_trees(rng: np.random.Generator) -> None:
    # one big mesh -> a deep BVH; clustered and degenerate triangles stress the SAH build
    scene = tracer.Scene()
    v, f = reference.random_mesh(rng, 3000, size=1.0)
    v[: len(v) // 3] *= 1e-4  # a dense cluster near the origin
    f[:50, 2] = f[:50, 1]  # degenerate triangles (two equal indices)
    g = scene.add_geometry(v, f)
    scene.add_instance(g, np.eye(4))
    scene.commit()
    o, d = _random_rays(rng, 150, spread=1.0)
    ours = scene.intersect(o, d)
    ref = reference.intersect(scene, o, d)
    assert_same_hits(scene, ours, ref, o, d)
    assert not np.isin(ours.primitive, np.arange(50)).any()


def test_large_rotated_meshes_match_brute_force(rng: np.random.Generator) -> None:
    # meshes above tlas.EXACT_MAX_TRIANGLES are bounded by their BVH's transformed second level:
    # random affine instances (mirrored, sheared) of a soup and of a thin strip must lose no hit
    from tracer.accel.tlas import EXACT_MAX_TRIANGLES

    scene = tracer.Scene()
    soup = reference.random_mesh(rng, EXACT_MAX_TRIANGLES + 200)
    k = np.arange(EXACT_MAX_TRIANGLES + 300)
    strip = (np.stack([k / len(k), 0.02 * (k % 2) + 0.1 * np.sin(k / 40), 0.1 * np.cos(k / 50)], 1),
             np.stack([k[:-2], k[1:-1], k[2:]], 1))
    for v, f in (soup, strip):
        g = scene.add_geometry(v, f)
        for _ in range(3):
            scene.add_instance(g, reference.random_affine(rng, spread=1.5))
    scene.commit()
    o, d = _random_rays(rng, 300, spread=2.0)
    ours = scene.intersect(o, d)
    ref = reference.intersect(scene, o, d)
    assert np.isfinite(ref.t).sum() > 50
    assert_same_hits(scene, ours, ref, o, d)


@pytest.mark.parametrize("seed", [4, 5])
def test_one_instance_scene_matches_brute_force(seed: int) -> None:
    # a top level with one instance is entered without its box test (tracer.accel.traverse.walk_scene)
    rng = np.random.default_rng(seed)
    scene = tracer.Scene()
    v, f = reference.random_mesh(rng, 200)
    scene.add_instance(scene.add_geometry(v, f), reference.random_affine(rng, spread=0.2, mirror=True))
    scene.commit()
    o, d = _random_rays(rng, 400, spread=2.0)
    ours = scene.intersect(o, d)
    ref = reference.intersect(scene, o, d)
    assert 50 < np.isfinite(ref.t).sum() < 350   # hits and misses both
    assert_same_hits(scene, ours, ref, o, d)
    hit = np.isfinite(ref.t)
    short = np.where(hit, ref.t * 0.999, 1e3)
    assert np.all(scene.intersect(o, d, short).instance == -1)
    assert not scene.occluded(o, d, short).any()
    np.testing.assert_array_equal(scene.occluded(o, d, np.where(hit, ref.t * 1.001, 1e3)), hit)
