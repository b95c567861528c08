"""Photon batches on CUDA (issue 27, tracer/gpu/transport.py, tracer/gpu/backend.py), without a GPU.

In numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``): a forward and a backward illuminance query through
``Simulation(..., backend=CudaBackend())`` agree with the CPU's answer within 4 combined standard errors
(|ΔE| ≤ 4 √(σ₁² + σ₂²), independent seeds) and say they ran on ``cuda``; on the CPU's seed they give the CPU's very
batches (the simulator runs the kernels' njit callees as the CPU's code; a card may round differently); a point
source over a black floor gives E = I cosθ / r² within 4 of the estimate's own standard errors; a card reported
full answers on the CPU with the reason, nothing raised; two concurrent queries never run on the card at once.
That both batch kernels compile to sm_90 PTX is tests/tracer/gpu/test_gpu_ptx.py's.

Each part runs in a child process (the simulator is chosen at numba-cuda's import). Skipped, saying why, where
numba-cuda (or, for PTX, NVVM) is missing.
"""

from __future__ import annotations

import importlib.util
import os

import numpy as np
import pytest

from tests.tracer.gpu.test_gpu_ptx import ROOT
from tests.tracer.gpu.test_gpu_traverse import run_child

Z = 4.0   # combined standard errors allowed between two estimates (the issue's |ΔE| ≤ 4σ)


@pytest.fixture(scope="module")
def simulated():
    if importlib.util.find_spec("numba_cuda") is None:
        pytest.skip("numba-cuda is not installed (pip install -e '.[gpu]')")
    env = {**os.environ, "NUMBA_ENABLE_CUDASIM": "1", "PYTHONPATH": str(ROOT)}
    return run_child("gpu_sim_transport.py", env, "room", "floor", "oom", "uploads", "lock")


def within(a: dict, b: dict) -> tuple[bool, np.ndarray]:
    la, lb = np.asarray(a["lux"]), np.asarray(b["lux"])
    sigma = np.sqrt(np.asarray(a["stderr"]) ** 2 + np.asarray(b["stderr"]) ** 2)
    z = np.abs(la - lb) / sigma
    return bool(np.all(z <= Z)), z


@pytest.mark.parametrize("estimator", ["forward", "backward"])
def test_room_agrees_with_the_cpu(simulated, estimator):
    """A Lambertian room lit by a point light: the card's answer (seed 2) and the CPU's (seed 1) are two independent
    estimates of the same illuminance; they agree within 4 combined standard errors."""
    assert simulated["simulator"] is True
    r = simulated["room"][estimator]
    cpu, gpu = r["cpu"], r["cuda"]
    assert gpu["estimator"] == cpu["estimator"] == estimator
    assert gpu["backend"] == {"name": "cuda", "device": "cuda:0 simulator"}, gpu["backend"]
    assert cpu["backend"]["name"] == "in-process"
    assert min(gpu["lux"]) > 0 and max(np.asarray(gpu["stderr"]) / np.asarray(gpu["lux"])) < 0.2, gpu
    budget = {"forward": 40_000, "backward": 6_000}[estimator]   # gpu_sim_transport.part_room's
    assert 0.5 * budget <= gpu["photons"] <= budget and 0.5 * budget <= cpu["photons"] <= budget
    ok, z = within(cpu, gpu)
    assert ok, (z, cpu, gpu)


@pytest.mark.parametrize("estimator", ["forward", "backward"])
def test_same_seed_same_batches_in_the_simulator(simulated, estimator):
    """One thread per batch, seeded by its index: on the same seed and the card's cut of the query
    (`tracer.gpu.backend.GPU_SHAPE`, thousands of small batches) the simulator (which runs the batch function as the
    CPU's compiled code) gives the very tallies of the CPU's threads running the same batches; a wrong batch index
    or weight would not."""
    r = simulated["room"][estimator]
    assert r["cpu_cut_as_cuda"]["backend"]["name"] == "in-process"
    assert r["cuda_seed_of_cpu"]["lux"] == r["cpu_cut_as_cuda"]["lux"]
    assert r["cuda_seed_of_cpu"]["stderr"] == r["cpu_cut_as_cuda"]["stderr"]
    assert r["cuda_seed_of_cpu"]["photons"] == r["cpu_cut_as_cuda"]["photons"]


@pytest.mark.parametrize("estimator", ["forward", "backward"])
def test_point_source_over_a_floor_closed_form(simulated, estimator):
    """E = I cosθ / r² (averaged over each receiver disk) within 4 of the estimate's own standard errors."""
    r = simulated["floor"]
    res = r[estimator]
    assert res["backend"]["name"] == "cuda"
    lux, err, exact = np.asarray(res["lux"]), np.asarray(res["stderr"]), np.asarray(r["exact"])
    assert np.all(err > 0) and np.all(err < 0.1 * exact), (err, exact)
    assert np.all(np.abs(lux - exact) <= Z * err), (lux, exact, err)


@pytest.mark.parametrize("estimator", ["forward", "backward"])
def test_scene_that_does_not_fit_runs_on_the_cpu(simulated, estimator):
    """The card reports 1 MiB free: the query is answered on the CPU (the very batches the card would have run, on
    the CPU's threads), and says why."""
    r = simulated["oom"][estimator]
    backend = r["answer"]["backend"]
    assert backend["name"] == "in-process", backend
    why = backend["fallback"]
    assert why.startswith("ran on the CPU because the scene needs") and "cuda:0 simulator" in why, why
    assert "which has 1.0 MiB free" in why, why
    assert r["equal_to_cpu"]


def test_a_kernel_that_fails_on_the_card_runs_on_the_cpu(simulated):
    """A kernel that fails on the card (here: its launch raises) is no crash: the query runs on the CPU, saying why."""
    backend = simulated["oom"]["kernel_failure"]["backend"]
    assert backend["name"] == "in-process", backend
    assert backend["fallback"] == ("ran on the CPU because the forward kernel failed on cuda:0 simulator: "
                                   "RuntimeError: launch failed (test)"), backend


def test_the_scene_stays_on_the_card(simulated):
    """The first query sends the whole scene; more queries of that revision (another Simulation, the other
    estimator) send nothing; the next revision after a move sends the instances and top levels only."""
    r = simulated["uploads"]
    store, top = set(r["store_fields"]), set(r["top_fields"])
    # 11 instance and top-level arrays, and the 10 of the elements with an inside (tracer.elements.table)
    assert len(store) == 10 and len(top) == 21 and not store & top, r
    assert len(r["first"]) == 1 and set(r["first"][0]) == store | top, r["first"]
    assert r["same_revision_uploads"] == 0, r
    assert len(r["after_move"]) == 1 and set(r["after_move"][0]) == top, r["after_move"]
    assert r["device"]["name"] == "cuda"


def test_one_gpu_job_at_a_time(simulated):
    """Two queries on two threads share one backend: their kernel runs (each held 50 ms) never overlap."""
    r = simulated["lock"]
    assert not r["errors"], r
    assert r["threads"] == 2 and r["runs"] >= 4, r
    assert r["overlaps"] == 0, r


def test_device_of_a_cuda_answer():
    from tracer.backends import device_of

    assert device_of({"name": "cuda", "device": "cuda:0 NVIDIA H100 80GB HBM3"}) == "cuda:0 NVIDIA H100 80GB HBM3"
    assert device_of({"name": "in-process", "threads": 2, "fallback": "ran on the CPU because …"}) == "cpu:2 threads"
