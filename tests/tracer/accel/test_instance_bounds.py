"""An instance's world box in the top level: it encloses every triangle, and for a rotated part it is
the box of the part, not the (looser) box of its rotated object box."""

from __future__ import annotations

import numpy as np
import pytest

import tracer
from tracer.accel import reference
from tracer.accel.tlas import EXACT_MAX_TRIANGLES, PAD
from tracer.errors import NotCommittedError, UnknownIdError


def _diagonal_strip(n_triangles: int) -> tuple[np.ndarray, np.ndarray]:
    """A thin strip along the object box's diagonal (0,0,0)-(1,1,1)."""
    k = np.arange(n_triangles + 2)
    s = k / (n_triangles + 1)
    v = np.stack([s, s, s], 1) + 0.002 * (k % 2)[:, None] * np.array([1.0, -1.0, 0.0])
    return v, np.stack([k[:-2], k[1:-1], k[2:]], 1)


def _diagonal_to_x() -> np.ndarray:
    """A rotation taking (1,1,1)/sqrt(3) to +x, as a 4x4 with a translation."""
    a = np.array([1.0, 1.0, 1.0]) / np.sqrt(3)
    b = np.array([1.0, 0.0, 0.0])
    v = np.cross(a, b)
    c = float(a @ b)
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    m = np.eye(4)
    m[:3, :3] = np.eye(3) + vx + vx @ vx / (1 + c)
    m[:3, 3] = [5.0, -2.0, 3.0]
    return m


def _world(v: np.ndarray, m: np.ndarray) -> np.ndarray:
    return v.astype(np.float32).astype(float) @ m[:3, :3].T + m[:3, 3]


def _corner_box(v: np.ndarray, m: np.ndarray) -> np.ndarray:
    lo, hi = v.min(0), v.max(0)
    corners = np.array([[(lo, hi)[(c >> a) & 1][a] for a in range(3)] for c in range(8)])
    w = _world(corners, m)
    return np.stack([w.min(0), w.max(0)])


def _area(box: np.ndarray) -> float:
    e = box[1] - box[0]
    return float(2 * (e[0] * e[1] + e[1] * e[2] + e[2] * e[0]))


def _rotated_strip_box(n_triangles: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(committed box, world vertices, corner box) of a diagonal strip rotated onto x."""
    v, f = _diagonal_strip(n_triangles)
    m = _diagonal_to_x()
    scene = tracer.Scene()
    i = scene.add_instance(scene.add_geometry(v, f), m)
    scene.commit()
    return scene.instance_bounds(i), _world(v, m), _corner_box(v, m)


def test_small_mesh_box_is_its_transformed_vertices_box() -> None:
    box, w, corners = _rotated_strip_box(40)
    np.testing.assert_allclose(box, np.stack([w.min(0), w.max(0)]), rtol=0, atol=10 * PAD * np.abs(w).max())
    assert np.all(box[0] <= w.min(0)) and np.all(box[1] >= w.max(0))
    assert _area(box) < 0.05 * _area(corners)


def test_large_mesh_box_encloses_it_and_is_tighter_than_the_corner_box() -> None:
    box, w, corners = _rotated_strip_box(EXACT_MAX_TRIANGLES * 4)
    assert np.all(box[0] <= w.min(0)) and np.all(box[1] >= w.max(0))
    # 16 second-level boxes of side about 1/16 along the diagonal, against the rotated unit cube
    assert _area(box) < 0.25 * _area(corners)


def test_random_affine_boxes_enclose_every_vertex(rng: np.random.Generator) -> None:
    scene = tracer.Scene()
    placed = []
    for n in (5, EXACT_MAX_TRIANGLES, EXACT_MAX_TRIANGLES + 1, 3000):
        v, f = reference.random_mesh(rng, n)
        g = scene.add_geometry(v, f)
        for _ in range(3):
            m = reference.random_affine(rng, spread=1e3)
            placed.append((scene.add_instance(g, m), n, _world(v[np.unique(f)], m)))
    scene.commit()
    for i, n, w in placed:
        box = scene.instance_bounds(i)
        assert np.all(box[0] <= w.min(0)) and np.all(box[1] >= w.max(0))
        if n <= EXACT_MAX_TRIANGLES:   # the vertices' box, up to the padding
            np.testing.assert_allclose(box, np.stack([w.min(0), w.max(0)]), rtol=0, atol=10 * PAD * np.abs(w).max())


def test_box_follows_a_move_and_is_not_read_before_commit() -> None:
    v, f = _diagonal_strip(10)
    scene = tracer.Scene()
    i = scene.add_instance(scene.add_geometry(v, f), np.eye(4))
    scene.commit()
    before = scene.instance_bounds(i)
    m = _diagonal_to_x()
    scene.set_transform(i, m)
    with pytest.raises(NotCommittedError, match="commit"):
        scene.instance_bounds(i)
    scene.commit()
    w = _world(v, m)
    np.testing.assert_allclose(scene.instance_bounds(i), np.stack([w.min(0), w.max(0)]), atol=1e-9)
    assert not np.allclose(before, scene.instance_bounds(i))
    with pytest.raises(UnknownIdError):
        scene.instance_bounds(i + 1)
    scene.remove_instance(i)
    scene.commit()
    with pytest.raises(UnknownIdError):
        scene.instance_bounds(i)
