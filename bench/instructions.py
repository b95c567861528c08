"""Instructions per ray, for work on the traversal: a count that a shared machine does not disturb.

Wall times here swing by about 30 % between runs of the same code (the neighbours' load changes the
instructions per cycle); the number of instructions a ray costs does not. Run under ``perf stat`` twice,
with ``reps`` and with 0, and divide the difference by ``reps`` times the ray count it prints (one
thread, so no worker spins)::

    for r in 0 5; do NUMBA_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \\
        perf stat -x, -e instructions .venv/bin/python bench/instructions.py scene3 incoherent $r; done

Scenes: ``mesh`` (the benchmark's 1M-triangle bumpy sphere), ``scene3`` (the paper's scene 3, two
levels), ``flat3`` (scene 3 as one flattened BVH). Rays: ``incoherent`` or ``camera``, as in
``bench/bench_tracer.py``, or ``point`` (random directions from the scene's centre). 200,000 rays, or
``BENCH_RAYS`` (the benchmark traces 1,000,000: a camera's rays are then more coherent).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import tracer  # noqa: E402
from bench.tracer_scenes import (  # noqa: E402
    bumpy_sphere,
    camera_rays,
    incoherent_rays,
    load_scene,
    synth_scene,
    world_triangles,
)

RAYS = int(os.environ.get("BENCH_RAYS", 200_000))


def scene_and_rays(name: str, kind: str) -> tuple[tracer.Scene, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(1)
    if name == "mesh":
        v, f = bumpy_sphere(1000, 500)
        s = tracer.Scene()
        s.add_instance(s.add_geometry(v, f), np.eye(4))
        s.commit()
        lo, hi, eye, target, fov = np.full(3, -0.7), np.full(3, 0.7), np.array([0.0, -3.5, 0.5]), np.zeros(3), 40.0
    elif name in ("scene3", "flat3"):
        v, f, m, world = synth_scene(3, 20_968, 302_822)
        s, _, _ = load_scene(v, f, m)
        s.commit()
        if name == "flat3":
            tri = world_triangles(s)
            s = tracer.Scene()
            s.add_instance(s.add_geometry(tri.reshape(-1, 3), np.arange(len(tri) * 3).reshape(-1, 3)), np.eye(4))
            s.commit()
        c = np.full(3, world / 2)
        lo, hi, eye, target, fov = np.zeros(3), np.full(3, world), c + np.array([0.3, -1.6, 0.4]) * world, c, 50.0
    else:
        raise SystemExit(f"unknown scene {name!r}: mesh, scene3 or flat3")
    if kind == "incoherent":
        o, d = incoherent_rays(rng, RAYS, lo, hi)
    elif kind == "camera":
        o, d = camera_rays(RAYS, eye, target, fov)
    elif kind == "point":   # one origin, random directions: a point source's rays
        d = rng.normal(size=(RAYS, 3))
        o = np.tile((lo + hi) / 2, (RAYS, 1))
    else:
        raise SystemExit(f"unknown rays {kind!r}: incoherent, camera or point")
    return s, o, d


def main() -> None:
    if len(sys.argv) != 4:
        raise SystemExit("usage: instructions.py SCENE RAYS REPS")
    s, o, d = scene_and_rays(sys.argv[1], sys.argv[2])
    print(f"{len(o)} rays", file=sys.stderr)
    s.intersect(o[:100], d[:100], threads=1)   # compile or load the kernels in both runs
    for _ in range(int(sys.argv[3])):
        s.intersect(o, d, threads=1)


if __name__ == "__main__":
    main()
