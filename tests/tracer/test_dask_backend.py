"""Photon batches on a real Dask cluster (issue 25): a `dask scheduler` and `dask worker` processes on loopback.

The facts: an answer computed on the cluster is bit-identical to the in-process answer for the same seed (forward
and backward, points and grids); a worker killed mid-query changes nothing; a scheduler that is not there, or
goes away mid-query, is a `BackendUnavailable` within the backend's timeouts, never a hang.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from bench.dask_cluster import dask_cluster
from tracer.backends import IN_PROCESS, BackendUnavailable, DaskBackend, Shipment
from tracer.scene import Scene
from tracer.simulate import Simulation
from tracer.warmup import box


def _glass_scene() -> tuple[Scene, dict, list]:
    """A point light over a floor with a glass block between: forward transport through Fresnel interfaces."""
    s = Scene()
    floor = s.add_instance(s.add_geometry(*box([-2, -2, -0.1], [2, 2, 0])), np.eye(4))
    glass = s.add_instance(s.add_geometry(*box([-0.3, -0.3, 0.5], [0.3, 0.3, 0.8])), np.eye(4))
    s.commit()
    return (s, {floor: {"type": "lambertian", "reflectance": 0.5}, glass: {"type": "dielectric", "ior": 1.5}},
            [{"type": "point", "position": [0, 0, 1.5], "intensity_cd": 100.0}])


def _diffuse_scene() -> tuple[Scene, dict, list]:
    """A floor and a wall, both Lambertian, lit by a point light: the backward estimator applies."""
    s = Scene()
    floor = s.add_instance(s.add_geometry(*box([-2, -2, -0.1], [2, 2, 0])), np.eye(4))
    wall = s.add_instance(s.add_geometry(*box([1, -2, 0], [1.1, 2, 2])), np.eye(4))
    s.commit()
    return (s, {floor: {"type": "lambertian", "reflectance": 0.5}, wall: {"type": "lambertian", "reflectance": 0.8}},
            [{"type": "point", "position": [0, 0, 1.5], "intensity_cd": 100.0}])


POINTS = np.array([[0.0, 0, 0], [0.15, 0.05, 0], [0.8, 0.5, 0]])
NORMALS = np.tile([0, 0, 1.0], (3, 1))


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    with dask_cluster(tmp_path_factory.mktemp("dask"), workers=2) as c:
        yield c


def _same(a, b) -> None:
    assert np.array_equal(a.lux, b.lux) and np.array_equal(a.stderr, b.stderr), (a.lux, b.lux)
    assert (a.photons, a.batches, a.stop_reason, a.counters) == (b.photons, b.batches, b.stop_reason, b.counters)


def test_answers_on_a_real_dask_cluster_are_bit_identical_to_in_process(cluster):
    backend = DaskBackend(cluster.address)
    try:
        scene, mats, lights = _glass_scene()
        here, there = Simulation(scene, mats, lights), Simulation(scene, mats, lights, backend=backend)
        a = here.illuminance(POINTS, NORMALS, max_photons=480_000, seed=7, estimator="forward")
        b = there.illuminance(POINTS, NORMALS, max_photons=480_000, seed=7, estimator="forward")
        _same(a, b)
        assert a.lux[0] > 0 and a.backend == IN_PROCESS.describe()
        assert b.backend["name"] == "dask" and b.backend["workers"] == 2 and b.backend["address"] == cluster.address
        g_here = here.grid([-1, -1, 0], [2, 0, 0], [0, 2, 0], 4, 3, max_photons=320_000, seed=3)
        g_there = there.grid([-1, -1, 0], [2, 0, 0], [0, 2, 0], 4, 3, max_photons=320_000, seed=3)
        _same(g_here, g_there)
        assert g_there.lux.shape == (3, 4) and g_there.backend["name"] == "dask"

        scene, mats, lights = _diffuse_scene()
        here, there = Simulation(scene, mats, lights), Simulation(scene, mats, lights, backend=backend)
        a = here.illuminance(POINTS, NORMALS, max_photons=20_000, seed=5, estimator="backward")
        b = there.illuminance(POINTS, NORMALS, max_photons=20_000, seed=5, estimator="backward")
        assert a.estimator == b.estimator == "backward"
        _same(a, b)
        # a target-error stop decides on the same numbers, so it stops at the same batch
        a = here.illuminance(POINTS, NORMALS, target_relative_error=0.03, max_seconds=120, seed=9)
        b = there.illuminance(POINTS, NORMALS, target_relative_error=0.03, max_seconds=120, seed=9)
        assert a.stop_reason == "target_relative_error"
        _same(a, b)
    finally:
        backend.close()


def test_progress_cancellation_and_time_budgets_work_on_the_cluster(cluster):
    backend = DaskBackend(cluster.address)
    try:
        scene, mats, lights = _glass_scene()
        sim = Simulation(scene, mats, lights, backend=backend)
        seen = []
        r = sim.illuminance(POINTS, NORMALS, max_photons=10**9, estimator="forward", seed=1,
                            progress=lambda p, w, s: seen.append(p), cancel=lambda: len(seen) >= 3)
        assert r.stop_reason == "cancelled" and len(seen) == 3 and seen[0] == 0 < seen[1] < seen[2] == r.photons
        r = sim.illuminance(POINTS, NORMALS, max_seconds=1.0, estimator="forward", seed=1)
        assert r.stop_reason == "max_seconds" and r.photons > 0 and r.backend["name"] == "dask"
    finally:
        backend.close()


def test_a_snapshot_goes_to_the_workers_once_per_content():
    scene, mats, lights = _glass_scene()
    sim = Simulation(scene, mats, lights)
    assert sim.snapshot("white") is sim.snapshot("white")
    same = Simulation(scene, mats, lights).snapshot("white")
    assert same is not sim.snapshot("white") and same.key == sim.snapshot("white").key
    moved = Simulation(scene, {**mats, 0: {"type": "lambertian", "reflectance": 0.4}}, lights).snapshot("white")
    assert moved.key != same.key
    assert Shipment((np.arange(3.0), 1)).key != Shipment((np.arange(3), 1)).key   # dtype counts, not only bytes


def test_a_worker_killed_mid_query_changes_nothing(tmp_path):
    scene, mats, lights = _glass_scene()
    expected = Simulation(scene, mats, lights).illuminance(POINTS, NORMALS, max_photons=3_200_000, seed=11,
                                                           estimator="forward")
    with dask_cluster(tmp_path, workers=2) as c:
        backend = DaskBackend(c.address, stall_timeout=60)
        killed = []

        def progress(photons, worst, seconds):
            if photons and not killed:   # after the first round: the next rounds find one worker gone
                c.workers[1].kill()
                killed.append(photons)

        try:
            got = Simulation(scene, mats, lights, backend=backend).illuminance(
                POINTS, NORMALS, max_photons=3_200_000, seed=11, estimator="forward", progress=progress)
            assert killed and killed[0] < got.photons   # the kill happened before the query's end
            _same(expected, got)
            assert got.backend["workers"] == 1
        finally:
            backend.close()


def test_no_scheduler_at_the_address_is_a_clear_error_not_a_hang():
    from service_process import free_port

    scene, mats, lights = _glass_scene()
    backend = DaskBackend(f"tcp://127.0.0.1:{free_port()}", connect_timeout=2)
    t = time.monotonic()
    with pytest.raises(BackendUnavailable, match="does not answer"):
        Simulation(scene, mats, lights, backend=backend).illuminance(POINTS, NORMALS, max_photons=40_000)
    assert time.monotonic() - t < 30   # bounded by the connect timeout, not a hang
    with pytest.raises(ValueError, match="tcp://host:8786"):
        DaskBackend("127.0.0.1:8786")


def test_the_scheduler_gone_mid_query_is_a_clear_error(tmp_path):
    scene, mats, lights = _glass_scene()
    with dask_cluster(tmp_path, workers=1) as c:
        backend = DaskBackend(c.address, connect_timeout=2, stall_timeout=3)

        def progress(photons, worst, seconds):
            if photons:   # after the first round
                for p in (c.scheduler, *c.workers):
                    p.kill()

        t = time.monotonic()
        with pytest.raises(BackendUnavailable):
            Simulation(scene, mats, lights, backend=backend).illuminance(
                POINTS, NORMALS, max_photons=3_200_000, estimator="forward", progress=progress)
        assert time.monotonic() - t < 60
        backend.close()
