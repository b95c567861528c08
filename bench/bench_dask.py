"""Photon batches beyond one process: throughput on a real Dask cluster against in-process threads, the overhead
per round and per task, and a model of throughput against worker count past this machine's two cores.

The query: the diffuse room of `bench_transport` (forward photons, 9 floor points), a photon budget, the same seed
everywhere, so every configuration traces the very same batches (the answers are compared bit for bit). Side by
side in one run, interleaved, medians of the repetitions:

- in-process on one thread and on two (`numba.set_num_threads`), the embedded default;
- a real `dask scheduler` with one and with two `dask worker` processes of one thread each (`bench.dask_cluster`).

Overhead: a round of one-photon batches (one task per worker thread) costs the scheduler's round trip and
nothing else; per photon batch, the difference between a cluster's time per batch and the in-process one.
Model: a round of R batches over N one-thread workers takes ceil(R / N)·t_batch + o_round + N·o_task, with
t_batch, o_round and o_task measured here; throughput = R · photons per batch / that time.
"""

from __future__ import annotations

import math
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.bench_transport import INTENSITY, LIGHT, RHO, floor_points, room_scene
from bench.dask_cluster import dask_cluster


def _simulation(backend=None):
    from tracer.simulate import Simulation

    s, room = room_scene()
    return Simulation(s, {room: {"type": "lambertian", "reflectance": RHO}},
                      [{"type": "point", "position": list(LIGHT), "intensity_cd": INTENSITY}], backend=backend)


def _overhead_round(backend, sim, tasks: int, repeats: int) -> float:
    """Median seconds of a round of `tasks` one-photon batches (one per task): what a round costs beyond work.
    The query is one disk receiver, made the way `Simulation._forward` makes it."""
    from tracer.backends import Shipment
    from tracer.scene import Scene
    from tracer.transport.forward import SensorArrays

    scene = sim.snapshot("white")
    receivers = Scene()
    i = receivers.add_disk_sensor(np.array([2.0, 2.0, 0.001]), np.array([0.0, 0.0, 1.0]), 0.05)
    receivers.commit()
    bin0 = np.full(i + 1, -1, np.int64)
    bin0[i] = 0
    sens = SensorArrays(bin0, np.ones(i + 1, np.int64), np.ones(i + 1, np.int64), np.zeros(2, np.int64),
                        np.zeros((i + 1, 3)))
    query = Shipment((receivers.arrays(), sens, 1, 0))
    backend.run(("forward", "white"), scene, query, 0, tasks, 1)
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        backend.run(("forward", "white"), scene, query, 0, tasks, 1)
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def run(quick: bool) -> dict:
    import numba

    from tracer.backends import DaskBackend

    photons = 1_600_000 if quick else 6_400_000
    repeats = 3 if quick else 5
    pts, nrm = floor_points(3)
    rows: dict[str, list[float]] = {}
    answers: dict[str, tuple] = {}
    threads_before = numba.get_num_threads()

    def record(name, sim, threads=None):
        if threads is not None:
            numba.set_num_threads(threads)
        r = sim.illuminance(pts, nrm, max_photons=photons, seed=1, estimator="forward")
        numba.set_num_threads(threads_before)
        rows.setdefault(name, []).append(r.seconds / r.batches)
        answers[name] = (r.lux.tobytes(), r.stderr.tobytes(), r.photons, r.batches)
        return r

    here = _simulation()
    here.illuminance(pts, nrm, max_photons=1000, estimator="forward")   # compile or load the kernel
    print("bench_dask: in-process and a real cluster of 1 and 2 workers", file=sys.stderr, flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        backends = {}
        with dask_cluster(Path(tmp) / "one", workers=1) as one, dask_cluster(Path(tmp) / "two", workers=2) as two:
            for name, c in (("dask, 1 worker", one), ("dask, 2 workers", two)):
                backends[name] = DaskBackend(c.address)
                _simulation(backends[name]).illuminance(pts, nrm, max_photons=1000, estimator="forward")
            batches = 0
            for _ in range(repeats):   # interleaved: the machine is shared, drift hits every row alike
                batches = record("in-process, 1 thread", here, 1).batches
                record("in-process, 2 threads", here, 2)
                for name, backend in backends.items():
                    record(name, _simulation(backend))
            overhead = {name: {str(n): _overhead_round(b, _simulation(b), n, 3 * repeats) for n in (1, 2)}
                        for name, b in backends.items()}
            for b in backends.values():
                b.close()
    identical = len({v for v in answers.values()}) == 1
    per_batch = {name: statistics.median(v) for name, v in rows.items()}
    t_batch = per_batch["in-process, 1 thread"]
    o_round = overhead["dask, 2 workers"]["1"]
    o_task = max(0.0, overhead["dask, 2 workers"]["2"] - o_round)
    from tracer.simulate import FORWARD_BATCH, MAX_ROUND_BATCHES

    def modelled(n: int) -> float:
        rb = MAX_ROUND_BATCHES
        return rb * FORWARD_BATCH / (math.ceil(rb / n) * t_batch + o_round + n * o_task)

    model = {str(n): modelled(n) for n in (1, 2, 4, 8, 16, 32, 64, 128)}
    result = {"photons": photons, "batches": batches, "photons_per_batch": FORWARD_BATCH,
              "seconds_per_batch": per_batch,
              "photons_per_second": {k: FORWARD_BATCH / v for k, v in per_batch.items()},
              "round_overhead_seconds": overhead, "identical_answers": identical,
              "model": {"t_batch": t_batch, "o_round": o_round, "o_task": o_task,
                        "round_batches": MAX_ROUND_BATCHES,
                        "photons_per_second": model}}
    result["markdown"] = markdown(result)
    return result


def markdown(r: dict) -> str:
    base = r["seconds_per_batch"]["in-process, 1 thread"]
    md = [f"### Throughput: {r['photons']:,} photons ({r['batches']} batches of {r['photons_per_batch']:,}), "
          f"diffuse room, medians of interleaved runs", "",
          "| where the batches ran | photons/s | × one thread |", "| --- | ---: | ---: |"]
    for name, s in r["seconds_per_batch"].items():
        md.append(f"| {name} | {r['photons_per_batch'] / s:,.0f} | {base / s:.2f} |")
    md += ["", f"Every configuration gave the same answer to the last bit: **{r['identical_answers']}**.", ""]
    o = r["round_overhead_seconds"]
    md.append("Overhead of a round of one-photon batches (scheduler round trip, no work): " + "; ".join(
        f"{name}: {v['1'] * 1e3:.1f} ms with 1 task, {v['2'] * 1e3:.1f} ms with 2" for name, v in o.items()) + ".")
    m = r["model"]
    md += ["", f"Model (t_batch = {m['t_batch'] * 1e3:.1f} ms per {r['photons_per_batch']:,}-photon batch on one "
               f"thread, o_round = {m['o_round'] * 1e3:.1f} ms, o_task = {m['o_task'] * 1e3:.2f} ms; rounds of "
               f"{m['round_batches']} batches once a query has run {4 * m['round_batches']}): throughput against "
               f"one-thread workers, on paper past this machine's two cores.", "",
           "| workers | photons/s | × one thread | efficiency |", "| ---: | ---: | ---: | ---: |"]
    one = r["photons_per_batch"] / m["t_batch"]
    for n, v in m["photons_per_second"].items():
        md.append(f"| {n} | {v:,.0f} | {v / one:.1f} | {v / one / int(n):.0%} |")
    md += ["", "The model charges every task to the scheduler in turn (o_task × workers per round), so at rounds of "
               f"{m['round_batches']} batches the efficiency falls past ~16 workers and beyond {m['round_batches']} "
               "a round has fewer batches than workers: a larger cluster needs larger rounds (`MAX_ROUND_BATCHES`) or "
               "batches. The overheads were measured on this shared 2-core machine running the scheduler, the "
               "workers, the client (and other work) at once; a quiet scheduler takes ~1 ms per task."]
    return "\n".join(md)
