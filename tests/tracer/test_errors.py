"""Every bad input raises TracerError (a ValueError) naming the problem, and leaves the scene as it was."""

from __future__ import annotations

import numpy as np
import pytest

import tracer
from tracer.errors import NotCommittedError, UnknownIdError

V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
F = np.array([[0, 1, 2]])


@pytest.fixture
def scene() -> tracer.Scene:
    s = tracer.Scene()
    s.add_instance(s.add_geometry(V, F), np.eye(4))
    s.commit()
    return s


def _unchanged(scene: tracer.Scene, before) -> None:
    assert (scene.geometries(), scene.instances()) == before
    assert not scene.dirty


@pytest.mark.parametrize("vertices, triangles, normals, match", [
    ([[0, 0, 0], [1, 0, np.nan], [0, 1, 0]], F, None, "vertex 1 is not finite"),
    ([[0, 0, 0], [1e39, 0, 0], [0, 1, 0]], F, None, "not finite"),  # overflows float32
    (V, [[0, 1, 3]], None, "indices"),
    (V, [[0, -1, 2]], None, "indices"),
    (V[:, :2], F, None, "vertices must have shape"),
    (V, [[0, 1, 2, 0]], None, "triangles must have shape"),
    (V, [[0.0, 1.0, 2.0]], None, "integers"),
    (V.astype(complex), F, None, "real numbers"),
    (V, F, np.ones((2, 3)), "normals"),
    (V, F, [[0, 0, 1], [0, 0, np.inf], [0, 0, 1]], "normals must be finite"),
])
def test_bad_geometry(scene, vertices, triangles, normals, match) -> None:
    before = (scene.geometries(), scene.instances())
    with pytest.raises(tracer.TracerError, match=match):
        scene.add_geometry(vertices, triangles, normals)
    _unchanged(scene, before)


@pytest.mark.parametrize("transform, match", [
    (np.eye(3), "shape"),
    ([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, "x"]], "4x4"),
    (np.diag([1.0, 1.0, np.inf, 1.0]), "non-finite"),
    (np.diag([1.0, 0.0, 1.0, 1.0]), "singular"),
    (np.array([[1, 2, 3, 0], [2, 4, 6, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]]), "singular"),
    (np.diag([1.0, 1.0, 1.0, 2.0]), "affine"),
    (np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [1, 0, 0, 1.0]]), "affine"),
    (np.array([[0.3, 0.7, 1.1, 0], [1.3, -0.4, 0.9, 0], [1.6, 0.3, 2.0 + 1e-8, 0], [0, 0, 0, 1.0]]), "ill-conditioned"),
    (np.array([[1, 0, 0, np.nan], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]]), "non-finite"),
])
def test_bad_transform(scene, transform, match) -> None:
    before = (scene.geometries(), scene.instances())
    g = scene.geometries()[0]
    with pytest.raises(tracer.TracerError, match=match):
        scene.add_instance(g, transform)
    with pytest.raises(tracer.TracerError, match=match):
        scene.set_transform(0, transform)
    _unchanged(scene, before)
    np.testing.assert_array_equal(scene.instance_transform(0), np.eye(4))


def test_unknown_ids(scene) -> None:
    before = (scene.geometries(), scene.instances())
    with pytest.raises(UnknownIdError, match="unknown geometry id"):
        scene.add_instance("0" * 64, np.eye(4))
    with pytest.raises(UnknownIdError, match="unknown geometry id"):
        scene.geometry_arrays("nope")
    for bad in (1, -1, 7, True, "0", 0.0, None):
        for call in (scene.remove_instance, scene.instance_geometry, scene.instance_transform):
            with pytest.raises(UnknownIdError, match="unknown instance id"):
                call(bad)
        with pytest.raises(UnknownIdError, match="unknown instance id"):
            scene.set_transform(bad, np.eye(4))
    _unchanged(scene, before)
    scene.remove_instance(0)
    scene.commit()
    with pytest.raises(UnknownIdError, match="unknown instance id 0"):
        scene.remove_instance(0)  # removed ids are gone, and never reused
    assert scene.add_instance(scene.geometries()[0], np.eye(4)) == 1
    assert isinstance(UnknownIdError("x"), ValueError)


def test_bad_sensors(scene) -> None:
    before = (scene.geometries(), scene.instances())
    cases = [
        (lambda: scene.add_disk_sensor([0, 0], [0, 0, 1], 1.0), "center must have shape"),
        (lambda: scene.add_disk_sensor([0, 0, np.nan], [0, 0, 1], 1.0), "center must be finite"),
        (lambda: scene.add_disk_sensor([0, 0, 0], [0, 0, 0], 1.0), "normal must be non-zero"),
        (lambda: scene.add_disk_sensor([0, 0, 0], [0, 0, 1], 0.0), "radius"),
        (lambda: scene.add_disk_sensor([0, 0, 0], [0, 0, 1], np.nan), "radius"),
        (lambda: scene.add_disk_sensor([0, 0, 0], [0, 0, 1], "big"), "radius"),
        (lambda: scene.add_rect_sensor([0, 0, 0], [1, 0, 0], [2, 0, 0]), "parallel"),
        (lambda: scene.add_rect_sensor([0, 0, 0], [0, 0, 0], [0, 1, 0]), "parallel"),
        (lambda: scene.add_rect_sensor([0, 0, 0], [1, 0, 0], [0, np.inf, 0]), "finite"),
        (lambda: scene.add_rect_sensor("abc", [1, 0, 0], [0, 1, 0]), "origin"),
    ]
    for call, match in cases:
        with pytest.raises(tracer.TracerError, match=match):
            call()
    _unchanged(scene, before)


def test_queries_need_a_commit() -> None:
    s = tracer.Scene()
    o, d = np.zeros((1, 3)), np.ones((1, 3))
    with pytest.raises(NotCommittedError, match="never committed"):
        s.intersect(o, d)
    with pytest.raises(NotCommittedError, match="never committed"):
        s.arrays()
    s.commit()
    s.add_geometry(V, F)
    with pytest.raises(NotCommittedError, match="not committed"):
        s.occluded(o, d)
    s.commit()
    s.occluded(o, d)


@pytest.mark.parametrize("origins, directions, t_max, match", [
    (np.zeros((2, 2)), np.ones((2, 3)), np.inf, r"origins must have shape \(k, 3\)"),
    (np.zeros((2, 3)), np.ones(3), np.inf, "directions must have shape"),
    (np.zeros((2, 3)), np.ones((3, 3)), np.inf, "differ in length"),
    (np.array([[0, 0, 0], [0, np.nan, 0]]), np.ones((2, 3)), np.inf, "ray 1: origin is not finite"),
    (np.array([[0, 0, 0], [0, np.inf, 0]]), np.ones((2, 3)), np.inf, "ray 1: origin is not finite"),
    (np.zeros((3, 3)), np.array([[1, 0, 0], [1, 0, 0], [0, 0, 0]]), np.inf, "ray 2: direction is zero"),
    (np.zeros((2, 3)), np.array([[1, 0, 0], [np.inf, 0, 0]]), np.inf, "ray 1: direction is not finite"),
    (np.zeros((2, 3)), np.array([[1, 0, 0], [np.nan, 0, 0]]), np.inf, "ray 1: direction is not finite"),
    (np.zeros((2, 3)), np.ones((2, 3)), -1.0, "ray 0: t_max must be >= 0"),
    (np.zeros((2, 3)), np.ones((2, 3)), [1.0, np.nan], "ray 1: t_max"),
    (np.zeros((2, 3)), np.ones((2, 3)), [1.0, 2.0, 3.0], "t_max must be a scalar or have shape"),
    (np.zeros((2, 3), dtype=object), np.ones((2, 3)), 1.0, "origins must be real numbers"),
    (np.full((2, 3), "a"), np.ones((2, 3)), 1.0, "origins must be real numbers"),
])
def test_bad_rays(scene, origins, directions, t_max, match) -> None:
    with pytest.raises(tracer.TracerError, match=match):
        scene.intersect(origins, directions, t_max)
    with pytest.raises(tracer.TracerError, match=match):
        scene.occluded(origins, directions, t_max)


def test_bad_threads(scene) -> None:
    for bad in (0, -1, 10_000, 1.5, True, "2"):
        with pytest.raises(tracer.TracerError, match="threads"):
            scene.intersect(np.zeros((1, 3)), np.ones((1, 3)), threads=bad)


def test_degenerate_triangles_never_hit_nor_nan() -> None:
    s = tracer.Scene()
    v = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0], [0, 0, 0]], float)
    f = np.array([[0, 1, 2], [0, 0, 3], [0, 4, 3], [1, 1, 1]])  # collinear, repeated, coincident vertices
    s.add_instance(s.add_geometry(v, f), np.eye(4))
    s.commit()
    rng = np.random.default_rng(0)
    o = np.concatenate([rng.uniform(-1, 2, (200, 3)), [[0.5, 0, 1], [0, 0.5, -1], [1, 0, 0]]])
    d = np.concatenate([rng.normal(size=(200, 3)), [[0, 0, -1], [0, 0, 1], [-1, 0, 0]]])
    h = s.intersect(o, d)
    assert np.all(h.instance == -1) and np.all(np.isinf(h.t))
    assert not np.isnan(h.normal).any() and not np.isnan(h.u).any()
    assert not s.occluded(o, d).any()


def test_scene_ids_are_geometry_ids() -> None:
    """``add_geometry`` hashes the validated arrays itself (no second validation): same id as the spec."""
    from tracer.geometry_id import geometry_id

    rng = np.random.default_rng(5)
    s = tracer.Scene()
    for n in (None, rng.normal(size=(7, 3))):
        v = rng.normal(size=(7, 3))
        f = rng.integers(0, 7, (5, 3))
        assert s.add_geometry(v, f, n) == geometry_id(v, f, n)
    assert s.add_geometry(np.empty((0, 3)), np.empty((0, 3), int)) == geometry_id(np.empty((0, 3)),
                                                                                   np.empty((0, 3), int))


def test_transform_inverse_is_exact_on_a_known_matrix() -> None:
    """object_from_world is the inverse of world_from_object (checked through a round trip of points)."""
    rng = np.random.default_rng(6)
    m = np.eye(4)
    m[:3, :3] = rng.normal(size=(3, 3))
    m[:3, 3] = rng.normal(size=3) * 10
    s = tracer.Scene()
    s.add_instance(s.add_geometry(V, F), m)
    s.commit()
    sa = s.arrays()
    inv = np.linalg.inv(m)
    np.testing.assert_allclose(sa.object_from_world[0], inv[:3], rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(sa.world_from_object[0], m[:3])


def test_every_error_the_tracer_raises_has_the_one_root():
    """One error root per package: `except tracer.TracerError` catches whatever the tracer refuses."""
    import importlib
    import inspect
    import pkgutil

    import tracer
    from tracer.errors import TracerError

    public = []
    for info in pkgutil.walk_packages(tracer.__path__, "tracer."):
        module = importlib.import_module(info.name)
        for name, obj in vars(module).items():
            if (inspect.isclass(obj) and issubclass(obj, BaseException) and obj.__module__ == info.name
                    and not name.startswith("_")):
                public.append(obj)
    assert len(public) >= 10
    assert [c.__name__ for c in public if not issubclass(c, TracerError)] == []
