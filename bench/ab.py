"""A/B wall time of ``Scene.intersect`` (or of photon tracing) between two checkouts, for work on the
traversal.

Wall times on this shared machine swing by 30 % from one minute to the next, so two runs made one
after the other compare the neighbours' load as much as the code. Here both checkouts load the same
scene and rays (``bench/instructions.py``) in two worker processes, and the driver asks them in turn,
A B B A A B ..., for one timed pass each: each ratio B/A compares two passes made seconds apart.
It prints the median ratio (< 1: B is faster) and its range::

    .venv/bin/python bench/ab.py /path/to/checkout_a /path/to/checkout_b scene3 incoherent 8

Rays ``KIND/any`` (``camera/any``) time ``Scene.occluded`` on them as shadow segments instead (lengths uniform up
to 1.5 times the farthest closest hit, as the tracer bench's any-hit rows). Scene ``room`` with rays ``photons``
(or ``photons:N``) times forward photon tracing instead: 200,000 (N)
photons through the diffuse room of ``bench/bench_transport.py`` (``Simulation.illuminance``, nine floor points);
``mixed`` (``mixed:N``) adds a mirror block and a glass block to it; ``lux`` (``lux:N``) times the backward lux
kernel instead (200,000 paths over the nine points), ``camera`` (``camera:N``) the luminance kernel (480,000 paths from
an 80 x 60 camera, `bench/bench_luminance.py`'s view of the room).

``AB_ENV_B="NUMBA_OPT=1 NUMBA_CACHE_DIR=/tmp/o1"`` adds settings to checkout B's worker alone (A and B may then be one
checkout: an LLVM level against the default; give B its own numba cache, whose index does not key the level).

Each checkout needs ``bench/instructions.py`` (``bench/bench_transport.py`` for the room) and its own
``.venv`` (a symbolic link to this one will do); ``git worktree add`` makes a checkout of an older
commit. One thread each.
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import time
from collections.abc import Callable


def one_pass(scene: str, rays: str) -> Callable[[], object]:
    """The work of one timed pass, loaded with the code on ``sys.path`` and run once outside the timing."""
    if scene == "room":
        import numpy as np

        kind = rays.split(":")[0]
        if kind not in ("photons", "mixed", "lux", "camera"):
            raise SystemExit("scene room takes rays 'photons', 'mixed', 'lux' or 'camera', each with ':N' or not")
        photons = int(rays.split(":")[1]) if ":" in rays else {"lux": 200_000, "camera": 480_000}.get(kind, 200_000)
        from bench.bench_transport import floor_points, room_scene
        from tracer.simulate import Simulation

        s, room = room_scene()
        materials = {room: {"type": "lambertian", "reflectance": 0.5}}
        if rays.startswith("mixed"):   # a mirror block and a glass block on the floor: every bounce kind met
            from tracer.warmup import box

            for (lo, hi), body in ((((0.5, 0.5, 0.0), (1.5, 1.5, 1.0)), {"type": "mirror", "reflectance": 0.9}),
                                   (((2.5, 2.5, 0.0), (3.5, 3.5, 1.0)), {"type": "dielectric", "ior": 1.5})):
                materials[s.add_instance(s.add_geometry(*box(lo, hi)), np.eye(4))] = body
            s.commit()
        sim = Simulation(s, materials, [{"type": "point", "position": [2.0, 2.0, 2.5], "intensity_cd": 1000.0}])
        pts, nrm = floor_points(3)
        if kind == "lux":
            sim.illuminance(pts, nrm, max_photons=1000, estimator="backward")
            return lambda: sim.illuminance(pts, nrm, max_photons=photons, estimator="backward")
        if kind == "camera":
            from bench.bench_luminance import camera

            sim.run(camera(2, 2), max_photons=64)
            return lambda: sim.run(camera(80, 60), max_photons=photons)
        sim.illuminance(pts, nrm, max_photons=1000, estimator="forward")
        return lambda: sim.illuminance(pts, nrm, max_photons=photons, estimator="forward")
    from bench.instructions import scene_and_rays

    kind, _, query = rays.partition("/")
    sc, o, d = scene_and_rays(scene, kind)
    sc.intersect(o[:100], d[:100], threads=1)
    if query == "any":   # shadow segments as the bench's any-hit rows: lengths uniform up to the farthest hit
        import numpy as np

        from bench.tracer_scenes import shadow_t_max

        t = sc.intersect(o, d, threads=1).t
        tm = shadow_t_max(np.random.default_rng(2), len(o), 1.5 * float(np.max(t[np.isfinite(t)])))
        sc.occluded(o[:100], d[:100], tm[:100], threads=1)
        return lambda: sc.occluded(o, d, tm, threads=1)
    return lambda: sc.intersect(o, d, threads=1)


def worker(checkout: str, scene: str, rays: str) -> None:
    """Load the work with the code of ``checkout``, then time one pass per line read from stdin: the CPU seconds
    of this thread (the work runs on it: one thread), which a neighbour's load on the shared cores does not inflate
    as it does wall time."""
    sys.path.insert(0, checkout)
    work = one_pass(scene, rays)
    print("ready", flush=True)
    for _ in sys.stdin:
        t0 = time.thread_time()
        work()
        print(time.thread_time() - t0, flush=True)


def pairs(a: str, b: str, scene: str, rays: str, n: int) -> tuple[list[float], list[float]]:
    """CPU seconds of `n` passes in each checkout, taken in turn (A B B A ...); (times of A, times of B)."""
    env = dict(os.environ, NUMBA_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    env_b = dict(env, **dict(kv.split("=", 1) for kv in os.environ.get("AB_ENV_B", "").split()))
    procs = [subprocess.Popen([f"{r}/.venv/bin/python", __file__, "--worker", r, scene, rays], cwd=r, env=e,
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
             for r, e in ((a, env), (b, env_b))]
    for p in procs:
        if p.stdout is None or p.stdout.readline().strip() != "ready":
            raise SystemExit(f"worker {p.args[0]} did not start")
    times: list[list[float]] = [[], []]
    for i in range(n):
        for k in ((0, 1) if i % 2 == 0 else (1, 0)):
            p = procs[k]
            assert p.stdin is not None and p.stdout is not None
            p.stdin.write("go\n")
            p.stdin.flush()
            times[k].append(float(p.stdout.readline()))
    for p in procs:
        assert p.stdin is not None
        p.stdin.close()
        p.wait()
    return times[0], times[1]


def main(a: str, b: str, scene: str, rays: str, n: int) -> None:
    times = pairs(a, b, scene, rays, n)
    ratio = [tb / ta for ta, tb in zip(*times, strict=True)]
    print(f"{scene} {rays}: A {statistics.median(times[0]) * 1e3:.0f} ms, B {statistics.median(times[1]) * 1e3:.0f} ms,"
          f" B/A median {statistics.median(ratio):.3f} (range {min(ratio):.3f} to {max(ratio):.3f}, {n} pairs)")


if __name__ == "__main__":
    if len(sys.argv) == 5 and sys.argv[1] == "--worker":
        worker(*sys.argv[2:5])
    elif len(sys.argv) in (5, 6):
        main(*sys.argv[1:5], int(sys.argv[5]) if len(sys.argv) == 6 else 8)
    else:
        raise SystemExit("usage: ab.py CHECKOUT_A CHECKOUT_B SCENE RAYS [PAIRS]")
