"""Self-intersection: a secondary ray spawned with tracer.accel.spawn.offset_ray_origin from a hit point
does not re-hit its own surface, at scales 1e-3 .. 1e5 and far from the origin.

Uses a convex closed sphere: a reflected ray must leave it without any hit, a transmitted ray must
reach the far side (a different triangle, well away)."""

from __future__ import annotations

import numpy as np
import pytest

import tracer
from tracer.accel import reference
from tracer.accel.spawn import offset_ray_origin
from tracer.accel.traverse import hit_point


def _offset(p: np.ndarray, n: np.ndarray, d: np.ndarray) -> np.ndarray:
    return np.array([offset_ray_origin(*p[i], *n[i], *d[i]) for i in range(len(p))])


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3, 1e5])
@pytest.mark.parametrize("far", [False, True])
def test_spawned_rays_do_not_rehit(scale: float, far: bool, rng: np.random.Generator) -> None:
    v, f = reference.icosphere(3)
    scene = tracer.Scene()
    g = scene.add_geometry(v, f)
    m = np.eye(4)
    m[:3, :3] = reference.random_rotation(rng) * scale
    centre = np.array([3.0, -2.0, 1.0]) * scale * (10.0 if far else 0.0)
    m[:3, 3] = centre
    scene.add_instance(g, m)
    scene.commit()
    k = 400
    o = centre + rng.normal(size=(k, 3)) * 3 * scale
    o = centre + (o - centre) * (3 * scale / np.linalg.norm(o - centre, axis=1, keepdims=True))
    target = centre + rng.uniform(-0.5, 0.5, (k, 3)) * scale
    d = target - o
    h = scene.intersect(o, d)
    assert np.all(h.instance == 0)
    sa = scene.arrays()
    for how in ("o+td", "barycentric"):
        if how == "o+td":
            p = o + h.t[:, None] * d
        else:
            p = np.array([hit_point(sa, int(h.instance[i]), int(h.primitive[i]), h.u[i], h.v[i]) for i in range(k)])
        n = h.normal
        refl = d - 2.0 * np.einsum("ij,ij->i", d, n)[:, None] * n
        q = _offset(p, n, refl)
        again = scene.intersect(q, refl)
        assert np.all(again.instance == -1), f"{np.sum(again.instance >= 0)} reflected rays re-hit ({how})"
        q = _offset(p, n, d)
        through = scene.intersect(q, d)
        assert np.all(through.instance == 0)
        assert np.all(through.primitive != h.primitive)
        assert np.all(through.t * np.linalg.norm(d, axis=1) > 1e-3 * scale)


def test_offset_moves_to_the_side_of_the_direction() -> None:
    for p in ([0.0, 0.0, 0.0], [1e5, -1e5, 3.0], [1e-6, 2e-6, -1e-6]):
        for n in ([0, 0, 1.0], [0.6, 0.0, -0.8], [1.0, 1.0, 1.0]):
            for sign in (1.0, -1.0):
                d = sign * np.array(n) + np.array([0.3, -0.2, 0.1]) * 0.01
                q = np.array(offset_ray_origin(*p, *n, *d))
                side = np.dot(q - np.array(p), n) * sign
                assert side > 0
                assert np.linalg.norm(q - np.array(p)) < 1e-8 * max(1.0, np.abs(p).max())
