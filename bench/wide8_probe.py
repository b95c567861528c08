"""Probe for the bottom levels: what 8-wide float32 rows (:mod:`tracer.accel.rows8`) would gain there over today's
4-wide quantised rows, for walks of one ray.

The solid top level is held in both layouts since this stop: the lanes (incoherent rays) read the 4-wide rows,
walks of one ray (a camera's rays, light transport) the 8-wide ones (:func:`tracer.accel.traverse.walk_scene`). The
bottom levels are still 4-wide only. This probe builds one BVH as :mod:`tracer.accel.blas` does, lays it out both
ways, and times a walk of one ray over each (the same float64 watertight triangle test, :mod:`tracer.accel.triangle`)
on the same rays in alternating rounds (one thread), checking that they find the same hits. Scenes: ``mesh``
(the benchmark's 1M-triangle bumpy sphere) and ``flat3`` (the paper's scene 3 as one flattened BVH)::

    NUMBA_NUM_THREADS=1 BENCH_RAYS=1000000 .venv/bin/python bench/wide8_probe.py [mesh|flat3 ...]

Writes ``bench/results/wide8_probe.json``.

What the probe leaves out: 8-wide bottom levels in the lanes lost to the 4-wide ones (branch ``wide8``:
1.15-1.21x slower on incoherent rays, twice the branch mispredictions), so they would be a second layout of
every BVH (about three times the rows' memory: 52.8 MB beside 17.5 MB for the 1M-triangle mesh), with a cache
version for it.
"""

from __future__ import annotations

import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np
from numba import njit

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.instructions import scene_and_rays  # noqa: E402
from bench.tracer_scenes import bumpy_sphere, world_triangles  # noqa: E402
from tracer.accel import blas, rows4  # noqa: E402
from tracer.accel.rows8 import ROW, descend8, pack8, ray8, slab8  # noqa: E402
from tracer.accel.traverse import TOP8_BASE, TOP8_DIST, new_stacks  # noqa: E402
from tracer.accel.triangle import intersect_triangle, origin_setup, ray_setup  # noqa: E402
from tracer.accel.wide import MISS, pop_nearer, prefetch, traverse_rows  # noqa: E402

ROUNDS = 7


@njit(cache=True, error_model="numpy", _nrt=False)
def walk8(nf, ni, tri, ox, oy, oz, dx, dy, dz, stack, tstack):
    """Closest-hit distance along the ray through the 8-wide rows (nearest child first)."""
    kx, ky, kz, sx, sy, sz = ray_setup(dx, dy, dz)
    okx, oky, okz = origin_setup(ox, oy, oz, kx, ky, kz)
    onx, ony, onz, ofx, ofy, ofz, fx, fy, fz, fxe, fye, fze, xl, yl, zl = ray8(ox, oy, oz, dx, dy, dz)
    best_t = np.inf
    t32 = np.inf
    sp = TOP8_BASE
    ref = 0
    while True:
        if ref >= 0:
            r = ROW * ref
            m = slab8(nf, r, onx, ony, onz, ofx, ofy, ofz, fx, fy, fz, fxe, fye, fze, xl, yl, zl, t32, tstack,
                      TOP8_DIST)
            if m != 0:
                ref, sp = descend8(ni, r, m, stack, tstack, TOP8_DIST, sp)
                if ref >= 0:
                    for line in range(0, ROW, 16):
                        prefetch(nf, ROW * ref + line)
                else:
                    prefetch(tri, 9 * ((-ref - 1) >> 4))
                continue
        else:
            x = -ref - 1
            for j in range(x >> 4, (x >> 4) + (x & 15)):
                hit, t, _, _ = intersect_triangle(tri, j, okx, oky, okz, kx, ky, kz, sx, sy, sz, best_t)
                if hit:
                    best_t = t
                    t32 = np.float64(rows4.up32(t))
        ref, sp = pop_nearer(stack, tstack, sp, TOP8_BASE, best_t)
        if ref == MISS:
            return best_t


@njit(cache=True, error_model="numpy", _nrt=False)
def rays8(nf, ni, tri, o, d, out, stack, tstack):
    for i in range(o.shape[0]):
        out[i] = walk8(nf, ni, tri, o[i, 0], o[i, 1], o[i, 2], d[i, 0], d[i, 1], d[i, 2], stack, tstack)


@njit(cache=True, error_model="numpy", _nrt=False)
def rays4(bf, bi, tri, o, d, out, stack, tstack):
    for i in range(o.shape[0]):
        out[i] = traverse_rows(bf, bi, tri, 0, 0, o[i, 0], o[i, 1], o[i, 2], d[i, 0], d[i, 1], d[i, 2], np.inf,
                               False, stack, tstack)[1]


def alternate(run4, run8, n: int) -> dict:
    """Time ``run4`` and ``run8`` (each traces the same ``n`` rays) in :data:`ROUNDS` alternating rounds:
    median rates and the median of the rounds' speed-ups."""
    ratios, s4, s8 = [], [], []
    for _ in range(ROUNDS):
        t0 = time.perf_counter()
        run4()
        a = time.perf_counter() - t0
        t0 = time.perf_counter()
        run8()
        b = time.perf_counter() - t0
        ratios.append(a / b)
        s4.append(n / a / 1e6)
        s8.append(n / b / 1e6)
    return {"rays": n, "mrays4": statistics.median(s4), "mrays8": statistics.median(s8),
            "speedup": statistics.median(ratios), "speedup_range": [min(ratios), max(ratios)]}


def layouts(tri_v: np.ndarray) -> dict:
    """Both layouts of one BVH over ``tri_v`` (m, 9), and the triangles in leaf order."""
    order, nb, na, nn, nc = blas.build_meshes(tri_v, np.array([0, len(tri_v)]), 4, 1.0)
    boxes, refs, row_cnt = blas.collapse(nb, na, nn, np.zeros(1, np.int64), nc)
    wide4, _ = rows4.pack_wide(boxes, refs, row_cnt)
    rows8, _ = pack8(rows4.pack_rows(boxes, refs))
    return {"rows4": wide4, "rows8": rows8, "tri": rows4.leaf_order_f32(tri_v, order)}


def time_pair(lay: dict, o: np.ndarray, d: np.ndarray) -> dict:
    """Both walks over the same rays in alternating rounds: median rates, speed-up, and whether the hits agree."""
    r4, r8, tri = lay["rows4"], lay["rows8"], lay["tri"]
    stack, tstack = new_stacks()
    t4, t8 = np.empty(len(o)), np.empty(len(o))
    b4, i4 = r4.reshape(-1), r4.view(np.int32).reshape(-1)
    b8, i8 = r8.reshape(-1), r8.view(np.int32).reshape(-1)
    rays4(b4, i4, tri, o[:10], d[:10], t4, stack, tstack)   # compile or load outside the timing
    rays8(b8, i8, tri, o[:10], d[:10], t8, stack, tstack)
    res = alternate(lambda: rays4(b4, i4, tri, o, d, t4, stack, tstack),
                    lambda: rays8(b8, i8, tri, o, d, t8, stack, tstack), len(o))
    return {**res, "same_hits": bool(np.array_equal(t4, t8))}


def probe(name: str) -> dict:
    out: dict = {"scene": name}
    lay = None
    for kind in ("camera", "incoherent"):
        scene, o, d = scene_and_rays(name, kind)
        if lay is None:
            if name == "mesh":
                v, f = bumpy_sphere(1000, 500)
                tri_v = v.astype(np.float32).astype(np.float64)[f].reshape(-1, 9)
            else:
                tri_v = world_triangles(scene).reshape(-1, 9)
            lay = layouts(tri_v)
            out.update(rows4=len(lay["rows4"]), rows8=len(lay["rows8"]),
                       bytes4=lay["rows4"].nbytes, bytes8=lay["rows8"].nbytes)
        r = out[kind] = time_pair(lay, o, d)
        del scene
        print(f"{name} {kind}: today {r['mrays4']:.3f} Mrays/s, 8-wide {r['mrays8']:.3f}, speed-up"
              f" {r['speedup']:.2f} ({r['speedup_range'][0]:.2f}-{r['speedup_range'][1]:.2f}), same hits:"
              f" {r['same_hits']}")
    return out


def main() -> None:
    names = sys.argv[1:] or ["mesh", "flat3"]
    if not set(names) <= {"mesh", "flat3"}:
        raise SystemExit("scenes: mesh, flat3")
    res = {"rounds": ROUNDS, "scenes": [probe(n) for n in names]}
    path = Path(__file__).resolve().parent / "results" / "wide8_probe.json"
    path.write_text(json.dumps(res, indent=1))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
