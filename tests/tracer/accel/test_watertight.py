"""Watertightness: rays from inside a closed mesh, aimed exactly at its vertices and edge midpoints,
never escape (Woop, Benthin and Wald's test in float64, plus conservative box tests), even 1e5 m
from the origin, whether the coordinates are in the vertices or in the instance transform."""

from __future__ import annotations

import numpy as np
import pytest

import tracer
from tracer.accel import reference

CENTRE = np.array([1e5, -1e5, 1e5])


def _targets(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    edges = np.unique(np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1), axis=0)
    return np.concatenate([v, 0.5 * (v[edges[:, 0]] + v[edges[:, 1]])])


def _origins(rng: np.random.Generator, centre: np.ndarray, radius: float) -> np.ndarray:
    inner = rng.normal(size=(3, 3))
    inner *= (rng.uniform(0.1, 0.8, (3, 1)) * radius) / np.linalg.norm(inner, axis=1, keepdims=True)
    return np.concatenate([centre[None], centre + inner])


@pytest.mark.parametrize("where", ["vertices", "transform"])
def test_no_ray_escapes_a_closed_sphere_far_from_the_origin(where: str, rng: np.random.Generator) -> None:
    v, f = reference.icosphere(5, radius=10.0)  # 20,480 triangles
    scene = tracer.Scene()
    if where == "vertices":
        v = v + CENTRE
        g = scene.add_geometry(v, f)
        scene.add_instance(g, np.eye(4))
        world_v = scene.geometry_arrays(g)[0].astype(np.float64)  # exactly the stored float32 vertices
    else:
        g = scene.add_geometry(v, f)
        m = np.eye(4)
        m[:3, :3] = reference.random_rotation(rng)
        m[:3, 3] = CENTRE
        scene.add_instance(g, m)
        world_v = scene.geometry_arrays(g)[0].astype(np.float64) @ m[:3, :3].T + m[:3, 3]
    scene.commit()
    targets = _targets(world_v, f)
    for o in _origins(rng, CENTRE, 10.0):
        d = targets - o
        hits = scene.intersect(np.broadcast_to(o, d.shape), d)
        escaped = np.flatnonzero(hits.instance < 0)
        assert escaped.size == 0, f"{escaped.size} of {len(d)} rays escaped, e.g. towards {targets[escaped[:3]]}"
        # each ray ends on the sphere, at (about) its target
        np.testing.assert_allclose(hits.t, 1.0, atol=2e-3)
        assert not scene.occluded(np.broadcast_to(o, d.shape), d, 0.99).any()
        assert scene.occluded(np.broadcast_to(o, d.shape), d, 1.01).all()


def test_rays_along_axes_through_shared_vertices_of_a_grid(rng: np.random.Generator) -> None:
    # a flat grid of triangles; axis-aligned rays through every vertex and edge midpoint hit it
    n = 30
    x, y = np.meshgrid(np.arange(n + 1, dtype=float), np.arange(n + 1, dtype=float))
    v = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1)
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    f = np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)])
    scene = tracer.Scene()
    scene.add_instance(scene.add_geometry(v, f), np.eye(4))
    scene.commit()
    inner = _targets(v, f)
    inner = inner[(inner[:, 0] > 0) & (inner[:, 0] < n) & (inner[:, 1] > 0) & (inner[:, 1] < n)]
    for direction in ([0, 0, -1.0], [0.0, 0.0, 1.0], [1e-9, -2e-9, -1.0]):
        dvec = np.broadcast_to(np.array(direction), inner.shape)
        o = inner - 5.0 * dvec
        hits = scene.intersect(o, dvec)
        assert np.all(hits.instance == 0)
        np.testing.assert_allclose(hits.t, 5.0, rtol=1e-12)


def test_the_setup_catches_a_non_watertight_intersector() -> None:
    # the same rays slip through a plain Möller–Trumbore test (the brute-force reference): the
    # watertightness test above can fail
    v, f = reference.icosphere(5, radius=10.0)
    v = np.asarray(v + CENTRE, np.float32).astype(np.float64)
    targets = _targets(v, f)[:600]
    o = CENTRE + np.array([1.3, -2.1, 0.7])
    tri = v[f]
    escaped = sum(not np.isfinite(reference.ray_triangle_t(o, t - o, tri)[0]).any() for t in targets)
    assert escaped > 0
