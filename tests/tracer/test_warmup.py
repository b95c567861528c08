"""The background compile of a first query's kernels (`tracer.warmup`)."""

from __future__ import annotations

import numba
import numpy as np

from tracer import warmup
from tracer.scene import Scene


def test_a_scene_of_receivers_has_the_array_types_of_any_scene():
    """The child compiles the query kernels on a scene holding only receivers: that compiles the kernels a real
    scene runs only if every array has the same type (dtype, dimensions, layout)."""
    scene = Scene()
    scene.add_instance(scene.add_geometry(*warmup.box((0, 0, 0), (1, 2, 3))), np.eye(4))
    scene.add_instance(scene.add_geometry(*warmup.box((2, 0, 0), (3, 1, 1))), np.eye(4))
    scene.commit()
    assert numba.typeof(warmup.receivers_only()) == numba.typeof(scene.arrays())


def test_background_child_reports_every_stage_and_waiting_returns():
    child = warmup.Background()
    try:
        for stage in warmup.STAGES:
            assert child.wait(stage, timeout=600)
        assert child.join(timeout=60) == 0
        status = child.status()
        assert status["state"] == "ready", status
        assert set(status["seconds"]) == set(warmup.STAGES)
        assert all(s >= 0 for s in status["seconds"].values())
    finally:
        child.stop()
