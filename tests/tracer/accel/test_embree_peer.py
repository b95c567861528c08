"""The benchmark's Embree-with-instances peer (bench/embree_instances.py) traces the same scene as ours.

A peer that answered a different question would make its speed meaningless: on random instanced
scenes (mirrored, non-uniformly scaled) it must hit the same instance at the same distance as our
tracer, up to Embree's float32 arithmetic. The agreement test needs the bench extra (embreex) and is
skipped without it.
"""

from __future__ import annotations

import numpy as np
import pytest

import tracer
from bench import embree_instances
from tracer.accel import reference


def test_instanced_embree_agrees_with_ours() -> None:
    pytest.importorskip("embreex")
    rng = np.random.default_rng(7)
    scene = tracer.Scene()
    geoms, insts = [], []
    for k in range(3):
        v, f = reference.random_mesh(rng, 200)
        g = scene.add_geometry(v, f)
        geoms.append((v, f))
        for mirror in (False, True):
            m = reference.random_affine(rng, spread=1.5, mirror=mirror)
            assert scene.add_instance(g, m) == len(insts)
            insts.append((k, m))
    scene.commit()
    o = rng.uniform(-6, 6, (4000, 3))
    d = rng.uniform(-2, 2, (4000, 3)) - o
    ours = scene.intersect(o, d)
    es = embree_instances.InstancedScene(geoms, insts)
    t, inst = es.intersect(o, d)
    es.close()
    assert 0.2 < np.mean(ours.instance >= 0) < 0.95   # the rays test both hits and misses
    # rays that graze an edge within float32 rounding may legally differ
    agree = inst == ours.instance
    assert np.mean(agree) > 0.999
    hit = agree & (inst >= 0)
    np.testing.assert_allclose(t[hit], ours.t[hit], rtol=1e-4)


def test_missing_library_is_a_clear_error(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(embree_instances, "_LIB", None)
    assert not embree_instances.available()
    with pytest.raises(RuntimeError, match="embreex"):
        embree_instances.InstancedScene([], [])
