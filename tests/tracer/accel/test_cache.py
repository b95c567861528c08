"""The on-disk BLAS library: a BLAS built in one Scene is loaded, not rebuilt, by another; a corrupt,
truncated, foreign or outdated file is rebuilt and never trusted."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

import tracer
from tracer.accel import cache, reference


def _scene(tmp_path, mesh, m=None, **kw) -> tuple[tracer.Scene, str, tracer.UpdateStats]:
    scene = tracer.Scene(cache_dir=tmp_path, **kw)
    g = scene.add_geometry(*mesh)
    scene.add_instance(g, np.eye(4) if m is None else m)
    return scene, g, scene.commit()


@pytest.fixture
def mesh():
    return reference.icosphere(4)  # 5120 triangles: above the caching threshold


@pytest.fixture
def rays(rng: np.random.Generator):
    o = rng.normal(size=(500, 3)) * 3
    return o, rng.uniform(-0.5, 0.5, (500, 3)) - o


def _same(a: tracer.Scene, b: tracer.Scene, rays) -> None:
    ha, hb = a.intersect(*rays), b.intersect(*rays)
    np.testing.assert_array_equal(ha.t, hb.t)
    np.testing.assert_array_equal(ha.primitive, hb.primitive)


def test_round_trip_across_scenes(tmp_path, mesh, rays) -> None:
    a, g, s = _scene(tmp_path, mesh)
    assert (s.blas_built, s.blas_loaded) == (1, 0)
    assert cache.cache_path(tmp_path, g).is_file()
    b, _, s = _scene(tmp_path, mesh)
    assert (s.blas_built, s.blas_loaded) == (0, 1)
    _same(a, b, rays)
    assert not list(tmp_path.glob("*.tmp"))


def _corrupt_truncate(path, other):
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


def _corrupt_garbage(path, other):
    path.write_bytes(b"\x93NUMPY not really" * 50)


def _corrupt_flip(path, other):
    raw = bytearray(path.read_bytes())
    raw[len(raw) // 2] ^= 0xFF
    path.write_bytes(bytes(raw))


def _corrupt_foreign(path, other):
    shutil.copy(other, path)  # another geometry's (valid) file under this id


def _corrupt_version(path, other):
    with np.load(path) as z:
        d = dict(z)
    d["version"] = np.array("lumenlink-blas-0")
    with open(path, "wb") as fh:
        np.savez(fh, **d)


def _corrupt_topology(path, other):
    # a well-formed, correctly digested file whose tree is invalid (a cycle): must be rejected
    with np.load(path) as z:
        gid, order, node_a, node_n = str(z["gid"]), z["order"], z["node_a"].copy(), z["node_n"]
    node_a[0] = 0
    cache.save(path.parent, gid, order, node_a, node_n)


@pytest.mark.parametrize("corrupt", [_corrupt_truncate, _corrupt_garbage, _corrupt_flip, _corrupt_foreign,
                                     _corrupt_version, _corrupt_topology])
def test_bad_cache_file_is_rebuilt(tmp_path, mesh, rays, corrupt) -> None:
    a, g, _ = _scene(tmp_path, mesh)
    _, other_g, _ = _scene(tmp_path, reference.icosphere(4, radius=2.0))
    path = cache.cache_path(tmp_path, g)
    corrupt(path, cache.cache_path(tmp_path, other_g))
    b, _, s = _scene(tmp_path, mesh)
    assert (s.blas_built, s.blas_loaded) == (1, 0)
    _same(a, b, rays)
    c, _, s = _scene(tmp_path, mesh)  # the rebuild rewrote a good file
    assert (s.blas_built, s.blas_loaded) == (0, 1)


def test_small_geometries_are_cached_unless_told(tmp_path, rng) -> None:
    """Every mesh is kept by default (issue 42: a restart rebuilds no bottom level); a threshold can still be set."""
    _, g, _ = _scene(tmp_path, reference.random_mesh(rng, 10))
    assert cache.cache_path(tmp_path, g).is_file()
    _, g, s = _scene(tmp_path, reference.random_mesh(rng, 10), cache_min_triangles=512)
    assert not cache.cache_path(tmp_path, g).exists()


def test_missing_directory_is_created(tmp_path, mesh) -> None:
    _, g, _ = _scene(tmp_path / "a" / "b", mesh)
    assert cache.cache_path(tmp_path / "a" / "b", g).is_file()
