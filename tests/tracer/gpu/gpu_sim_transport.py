"""Photon batches through `tracer.gpu.backend.CudaBackend` in numba-cuda's simulator, beside the CPU: run by
tests/tracer/gpu/test_gpu_transport.py in a child with NUMBA_ENABLE_CUDASIM=1; prints one JSON object with the answers
(lux, stderr, photons, device), which the test compares.

Parts: ``room`` (forward and backward estimators in a Lambertian box room with a point light, CPU and CUDA on
different seeds, and CUDA on the CPU's seed), ``floor`` (a point source over a black floor: the closed form
E = I cosθ / r², averaged over each receiver disk), ``oom`` (the card's free memory reported as 1 MiB: the query
answers on the CPU, saying why), ``uploads`` (what each revision sends to the card), ``lock`` (two threads run
batches on one backend at once; each run's start and end).

Usage: NUMBA_ENABLE_CUDASIM=1 python tests/tracer/gpu/gpu_sim_transport.py room floor oom uploads lock
"""

from __future__ import annotations

import json
import os
import sys
import threading
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from tests.tracer.transport_scenes import box, disk_average, point_source_e, quad, scene_of  # noqa: E402
from tracer.simulate import Simulation  # noqa: E402

POINTS = np.array([[0.0, 0.0, 0.0], [1.0, 0.3, 0.0], [-0.6, 1.1, 0.0]])
UP = np.tile([0.0, 0.0, 1.0], (3, 1))
RADIUS = 0.3
LIGHT = {"type": "point", "position": [0.2, -0.1, 2.0], "intensity_cd": 1000.0}


def answer(res) -> dict:
    return {"lux": np.asarray(res.lux).tolist(), "stderr": np.asarray(res.stderr).tolist(), "photons": res.photons,
            "estimator": res.estimator, "backend": res.backend}


def room_sim(backend=None):
    """A Lambertian box room (4 × 4 × 2.5 m, ρ = 0.5) lit by a point light of 1000 cd."""
    s, ids = scene_of(box([-2, -2, 0], [2, 2, 2.5]))
    return Simulation(s, {ids[0]: {"type": "lambertian", "reflectance": 0.5}}, [LIGHT], backend=backend)


def part_room(cuda) -> dict:
    """The CPU with its own shape against the card (seed 2) and, on the card's shape, the CPU's batches (seed 1)."""
    from tracer.backends import InProcess

    cpu, gpu, cpu_cut_as_gpu = room_sim(), room_sim(cuda), room_sim(InProcess(shape=cuda.shape))
    out = {}
    for est, photons in (("forward", 40_000), ("backward", 6_000)):
        q = dict(radius=RADIUS, max_photons=photons, estimator=est)
        a = cpu.illuminance(POINTS, UP, seed=1, **q)
        b = gpu.illuminance(POINTS, UP, seed=2, **q)
        same_seed = gpu.illuminance(POINTS, UP, seed=1, **q)
        cut_as_gpu = cpu_cut_as_gpu.illuminance(POINTS, UP, seed=1, **q)
        out[est] = {"cpu": answer(a), "cuda": answer(b), "cuda_seed_of_cpu": answer(same_seed),
                    "cpu_cut_as_cuda": answer(cut_as_gpu)}
    return out


def part_floor(cuda) -> dict:
    """A point source 1.5 m over a black floor: only direct light arrives, E = I cosθ / r² (disk average)."""
    s, ids = scene_of(quad([-5, -5, 0], [10, 0, 0], [0, 10, 0]))
    light = {"type": "point", "position": [0.3, 0.2, 1.5], "intensity_cd": 500.0}
    sim = Simulation(s, {ids[0]: {"type": "black"}}, [light], backend=cuda)
    fn = point_source_e(500.0, light["position"], [0, 0, 1])
    exact = [disk_average(fn, p, [0, 0, 1], RADIUS) for p in POINTS]
    out = {"exact": exact}
    for est, photons in (("forward", 60_000), ("backward", 3_000)):
        out[est] = answer(sim.illuminance(POINTS, UP, radius=RADIUS, max_photons=photons, estimator=est, seed=3))
    return out


def part_oom(cuda) -> dict:
    import tracer.gpu.backend as gpu_backend
    from tracer.backends import InProcess

    free_bytes = gpu_backend.free_bytes
    gpu_backend.free_bytes = lambda: 1 << 20   # the card reports 1 MiB free
    fresh = gpu_backend.CudaBackend()           # nothing of this scene on the card yet
    out = {}
    try:
        for est in ("forward", "backward"):
            res = room_sim(fresh).illuminance(POINTS, UP, radius=RADIUS, max_photons=4_000, estimator=est, seed=1)
            cpu = room_sim(InProcess(shape=fresh.shape)).illuminance(   # the card's batches, on the CPU
                POINTS, UP, radius=RADIUS, max_photons=4_000, estimator=est, seed=1)
            out[est] = {"answer": answer(res), "equal_to_cpu": bool(np.array_equal(res.lux, cpu.lux))}
    finally:
        gpu_backend.free_bytes = free_bytes

    class Broken:   # a kernel that fails on the card (to compile, launch or finish)
        def __getitem__(self, cfg):
            def launch(*args):
                raise RuntimeError("launch failed (test)")
            return launch

    kernel, gpu_backend.forward_kernel = gpu_backend.forward_kernel, Broken()
    try:
        res = room_sim(cuda).illuminance(POINTS, UP, radius=RADIUS, max_photons=4_000, estimator="forward", seed=1)
        out["kernel_failure"] = answer(res)
    finally:
        gpu_backend.forward_kernel = kernel
    return out


def part_uploads(cuda) -> dict:
    """What reaches the card: a first query sends the whole scene, a second query of the same revision nothing, a
    query of the next revision after a move the top level only (each DeviceScene upload's fields, in order)."""
    import tracer.gpu.backend as gpu_backend

    sent: list[list[str]] = []
    update = gpu_backend.DeviceScene.update

    def counted(self, sa):
        fields = update(self, sa)
        sent.append(list(fields))
        return fields

    gpu_backend.DeviceScene.update = counted
    try:
        fresh = gpu_backend.CudaBackend()
        s, ids = scene_of(box([-2, -2, 0], [2, 2, 2.5]))
        mats = {ids[0]: {"type": "lambertian", "reflectance": 0.5}}
        q = dict(radius=RADIUS, max_photons=2_000, seed=1)
        Simulation(s, mats, [LIGHT], backend=fresh).illuminance(POINTS, UP, estimator="forward", **q)
        first = len(sent)
        sim = Simulation(s, mats, [LIGHT], backend=fresh)
        sim.illuminance(POINTS, UP, estimator="forward", **q)
        sim.illuminance(POINTS, UP, estimator="backward", **q)
        same_revision = len(sent) - first
        m = s.instance_transform(ids[0]).copy()
        m[:3, 3] += [0.05, 0.0, 0.0]
        s.set_transform(ids[0], m)
        s.commit()
        res = Simulation(s, mats, [LIGHT], backend=fresh).illuminance(POINTS, UP, estimator="forward", **q)
    finally:
        gpu_backend.DeviceScene.update = update
    return {"first": sent[:first], "same_revision_uploads": same_revision, "after_move": sent[first:],
            "device": res.backend, "store_fields": list(gpu_backend.STORE_FIELDS),
            "top_fields": list(gpu_backend.TOP_FIELDS)}


def part_lock(cuda) -> dict:
    """Two threads run rounds of batches on one backend at once; each run's (start, end), from inside the lock's
    hold (the kernel launch is wrapped to record them)."""
    import tracer.gpu.backend as gpu_backend

    spans: list[tuple[float, float, int]] = []
    launches = {"forward": gpu_backend.forward_kernel}

    class Timed:
        def __init__(self, kernel):
            self.kernel = kernel

        def __getitem__(self, cfg):
            launch = self.kernel[cfg]

            def run(*args):
                t0 = time.perf_counter()
                launch(*args)
                time.sleep(0.05)   # a run long enough for the other thread to try to start
                spans.append((t0, time.perf_counter(), threading.get_ident()))
            return run

    gpu_backend.forward_kernel = Timed(launches["forward"])
    sims = [room_sim(cuda), room_sim(cuda)]
    errors: list[str] = []

    def query(sim, seed):
        try:
            sim.illuminance(POINTS, UP, radius=RADIUS, max_photons=2_000, estimator="forward", seed=seed)
        except Exception as exc:   # noqa: BLE001 - reported
            errors.append(repr(exc))

    threads = [threading.Thread(target=query, args=(sim, k)) for k, sim in enumerate(sims)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    gpu_backend.forward_kernel = launches["forward"]
    spans.sort()
    overlaps = sum(1 for a, b in zip(spans, spans[1:], strict=False) if b[0] < a[1])
    return {"runs": len(spans), "threads": len({s[2] for s in spans}), "overlaps": overlaps, "errors": errors}


def main():
    from tracer.gpu.backend import CudaBackend
    from tracer.gpu.transport import SIMULATOR

    cuda = CudaBackend()
    out = {"simulator": SIMULATOR, "device": cuda.describe()}
    for part in sys.argv[1:]:
        out[part] = globals()[f"part_{part}"](cuda)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
