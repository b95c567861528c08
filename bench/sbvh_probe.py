"""Build time and hits of the bottom level with and without spatial splits (`tracer.accel.sbvh`), one checkout.

Run with each checkout's own interpreter and code (A: main, B: the branch), then compare the files::

    .venv/bin/python bench/sbvh_probe.py flat3 /tmp/hits_b.npz      # build seconds, rows, references
    .venv/bin/python bench/sbvh_probe.py compare /tmp/hits_a.npz /tmp/hits_b.npz

Scenes as in ``bench/instructions.py`` (``flat3``, ``mesh``, ``scene3``); the hits are those of its
``incoherent`` and ``camera`` rays (``BENCH_RAYS``, 200,000 each). The build time is the ``commit`` of the
scene (flat3: of the flattened mesh alone), best of three fresh scenes, after a warm-up commit.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import tracer  # noqa: E402
from bench.instructions import scene_and_rays  # noqa: E402
from bench.tracer_scenes import bumpy_sphere, load_scene, synth_scene, world_triangles  # noqa: E402


def build_seconds(name: str) -> float:
    warm = tracer.Scene()
    warm.add_instance(warm.add_geometry(*bumpy_sphere(20, 10)), np.eye(4))
    warm.commit()
    if name == "mesh":
        v, f = bumpy_sphere(1000, 500)
    else:
        v3, f3, m3, _ = synth_scene(3, 20_968, 302_822)
        s3, _, _ = load_scene(v3, f3, m3)
        s3.commit()
        tri = world_triangles(s3)
        v, f = tri.reshape(-1, 3), np.arange(len(tri) * 3).reshape(-1, 3)
    best = np.inf
    for _ in range(3):
        s = tracer.Scene()
        s.add_instance(s.add_geometry(v, f), np.eye(4))
        t0 = time.perf_counter()
        s.commit()
        best = min(best, time.perf_counter() - t0)
    st = s._blas
    print(f"{name}: commit {best:.3f} s, {len(st.store['bvh'])} wide rows, {len(st.store['tri_prim'])} leaf rows "
          f"for {len(f)} triangles")
    return best


def main() -> None:
    if sys.argv[1] == "compare":
        a, b = np.load(sys.argv[2]), np.load(sys.argv[3])
        for k in sorted(a.files):
            if k.endswith("_t"):
                ta, tb = a[k], b[k]
                pa, pb = a[k[:-2] + "_p"], b[k[:-2] + "_p"]
                same = np.mean((ta == tb) & (pa == pb))
                print(f"{k[:-2]}: agreement {same:.5f} ({int(np.sum(np.isfinite(ta)))} hits)")
        return
    name, out = sys.argv[1], sys.argv[2]
    if name in ("flat3", "mesh"):
        build_seconds(name)
    res: dict[str, Any] = {}
    for kind in ("incoherent", "camera"):
        s, o, d = scene_and_rays(name, kind)
        h = s.intersect(o, d, threads=1)
        res[f"{kind}_t"] = np.asarray(h.t)
        res[f"{kind}_p"] = np.asarray(h.primitive) * 1_000_000 + np.asarray(h.instance)
    np.savez(out, **res)


if __name__ == "__main__":
    main()
