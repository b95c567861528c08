"""Probe for the next step of issue 3: what 8-wide float32 rows would gain over today's 4-wide float64 rows.

Today a ray tests a wide row's four 8-bit quantised boxes in 4-lane double precision (63 instructions,
one cache line, :func:`tracer.kinds.mesh.slab4`); Embree tests eight float32 boxes in one AVX2 vector.
This probe builds the same binary BVH as :mod:`tracer.blas`, collapses it into 8-wide rows of unquantised
float32 planes (256 bytes, Embree's uncompressed ``BVH8`` node), and walks them with a *conservative*
float32 slab test; triangles are the same float64 watertight test (:mod:`tracer.triangle`). It times both
walks on the same rays in alternating rounds (one thread) and checks that they find the same hits.

The slab test stays conservative in float32: pbrt's form ``(p - o) inv`` (a rounding relative to the
distance) with the far distances scaled by ``1 + 2 gamma(3)``; the float64 origin rounded towards the near
plane for near distances and away from it for far ones; ``t_max`` rounded up. So it never culls a box
that the float64 test keeps, at any coordinate magnitude (far from the origin the boxes only grow by
float32's rounding of the origin).

Scenes ``mesh`` and ``flat3`` (one BVH) compare whole walks; ``scene3`` (two levels) makes only the top level
8-wide and walks each instance's bottom level as today (:func:`tracer.traverse._closest` against
:func:`walk8_top`).

Both walks here are single-ray walks. Built into the tracer (branch ``wide8``, 128-byte quantised rows,
all tests passing in the 256-byte form), the 8-wide rows lost to today's walk of incoherent rays, which
keeps four rays in flight (:mod:`tracer.lanes`): 1.15-1.21x slower (``bench/ab.py``), with twice the
branch mispredictions; camera rays, walked one at a time, gained 0.86-0.94 (256-byte rows) or nothing
(128-byte rows).

What it leaves to the real change: 8-wide rows in both levels of the scene and in :mod:`tracer.lanes`, the stack
bound (an 8-wide level pushes up to seven entries), :func:`tracer.tlas.world_boxes` and refits on the new
rows, a cache version, and the test suite for the float32 test. Delete this probe when that lands::

    NUMBA_NUM_THREADS=1 BENCH_RAYS=1000000 .venv/bin/python bench/wide8_probe.py [mesh|flat3|scene3 ...]

Writes ``bench/results/wide8_probe.json``.
"""

from __future__ import annotations

import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.bench_tracer import bumpy_sphere, world_triangles  # noqa: E402
from bench.instructions import scene_and_rays  # noqa: E402
from tracer import blas  # noqa: E402
from tracer.kinds import dispatch  # noqa: E402
from tracer.kinds.mesh import MISS, pop_nearer, prefetch, traverse_rows  # noqa: E402
from tracer.traverse import _closest, _to_object, new_stacks  # noqa: E402
from tracer.triangle import intersect_triangle, ray_setup  # noqa: E402

WIDTH = 8
#: float32 rounding allowance on far distances: 1 + 2 gamma(3), plus one ulp for rounding it to float32
FAR = 1.0 + 2.0 * (3 * 2.0**-24 / (1 - 3 * 2.0**-24)) + 2.0**-22
ROUNDS = 7


@njit(cache=True, error_model="numpy")
def widen8(boxes, refs):
    """One tree's binary child-box rows (:func:`tracer.blas.collapse`) as 8-wide rows: from a row's two
    children, open the interior child of largest area until eight (Embree builds its BVH8 so).
    Returns planes ``(W, 48)`` (``8 a + slot``, ``a`` = xmin .. zmax) and references ``(W, 8)``."""
    wboxes = np.empty((boxes.shape[0], 6 * WIDTH))
    wrefs = np.empty((boxes.shape[0], WIDTH), np.int64)
    queue = np.empty(boxes.shape[0] + 1, np.int64)
    src = np.empty(WIDTH, np.int64)   # 2 binary row + slot
    queue[0] = 0
    nw = 1
    k = 0
    while k < nw:
        src[0] = 2 * queue[k]
        src[1] = src[0] + 1
        used = 2
        while used < WIDTH:
            best = -1
            best_area = -1.0
            for c in range(used):
                s = src[c]
                if refs[s >> 1, s & 1] >= 0:
                    b = boxes[s >> 1]
                    o = 6 * (s & 1)
                    area = blas._area(b[o], b[o + 1], b[o + 2], b[o + 3], b[o + 4], b[o + 5])
                    if area > best_area:
                        best_area = area
                        best = c
            if best < 0:
                break
            child = 2 * refs[src[best] >> 1, src[best] & 1]
            src[best] = child
            src[used] = child + 1
            used += 1
        for slot in range(WIDTH):
            if slot < used:
                s = src[slot]
                for a in range(6):
                    wboxes[k, WIDTH * a + slot] = boxes[s >> 1, 6 * (s & 1) + a]
                ref = refs[s >> 1, s & 1]
                if ref >= 0:
                    queue[nw] = ref
                    ref = nw
                    nw += 1
                wrefs[k, slot] = ref
            else:
                for a in range(3):
                    wboxes[k, WIDTH * a + slot] = np.inf
                    wboxes[k, WIDTH * (a + 3) + slot] = -np.inf
                wrefs[k, slot] = -1
        k += 1
    return wboxes[:nw], wrefs[:nw]


@njit(cache=True, error_model="numpy")
def pack8(wboxes, wrefs, out_f, out_i):
    """Rows of 64 float32: the 48 planes rounded outward, then the 8 references (int32 view)."""
    for k in range(wboxes.shape[0]):
        for c in range(3 * WIDTH):
            out_f[k, c] = blas._down32(wboxes[k, c])
            out_f[k, 3 * WIDTH + c] = blas._up32(wboxes[k, 3 * WIDTH + c])
        for c in range(WIDTH):
            out_i[k, 6 * WIDTH + c] = wrefs[k, c]


@intrinsic
def slab8(typingctx, nf, r, onx, ony, onz, ofx, ofy, ofz, ix, iy, iz, ixe, iye, ize, xl, yl, zl, t_max, tbuf):
    """Conservative float32 slab test of the eight boxes of the row at ``nf[r]``: the mask of boxes hit;
    the eight entry distances are stored to ``tbuf``. ``on*``/``of*``: the origin rounded for near / far
    distances; ``i*``/``i*e``: the inverse direction, and times :data:`FAR`; ``xl`` etc. the near plane."""
    f32 = types.float32
    sig = types.int64(nf, types.int64, *(f32,) * 12, types.int64, types.int64, types.int64, f32, tbuf)

    def codegen(context, builder, sig, args):
        row = builder.gep(context.make_array(sig.args[0])(context, builder, args[0]).data, [args[1]], inbounds=True)
        out = context.make_array(sig.args[18])(context, builder, args[18]).data
        onx, ony, onz, ofx, ofy, ofz, ix, iy, iz, ixe, iye, ize, xl, yl, zl, t_max = args[2:18]
        i32 = ir.IntType(32)
        i64 = ir.IntType(64)
        v8 = ir.VectorType(ir.FloatType(), WIDTH)
        undef = ir.Constant(v8, ir.Undefined)

        def splat(x):
            return builder.shuffle_vector(builder.insert_element(undef, x, i32(0)), undef,
                                          ir.Constant(ir.VectorType(i32, WIDTH), [0] * WIDTH))

        def plane(p):
            ptr = builder.gep(row, [builder.mul(p, i64(WIDTH))], inbounds=True)
            return builder.load(builder.bitcast(ptr, v8.as_pointer()), align=4)

        tn = splat(ir.FloatType()(0.0))
        tf = splat(t_max)
        for a, (near, on, of, inv, inve) in enumerate(((xl, onx, ofx, ix, ixe), (yl, ony, ofy, iy, iye),
                                                      (zl, onz, ofz, iz, ize))):
            t0 = builder.fmul(builder.fsub(plane(near), splat(on)), splat(inv))
            t1 = builder.fmul(builder.fsub(plane(builder.sub(i64(2 * a + 3), near)), splat(of)), splat(inve))
            tn = builder.select(builder.fcmp_ordered(">", t0, tn), t0, tn)   # a NaN slab is ignored
            tf = builder.select(builder.fcmp_ordered("<", t1, tf), t1, tf)
        builder.store(tn, builder.bitcast(out, v8.as_pointer()), align=4)
        hit = builder.fcmp_ordered("<=", tn, tf)
        return builder.zext(builder.bitcast(hit, ir.IntType(WIDTH)), i64)
    return sig, codegen


@intrinsic
def lowest_bit(typingctx, x):
    """Index of the lowest set bit of ``x`` (> 0)."""
    def codegen(context, builder, sig, args):
        i64 = ir.IntType(64)
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(i64, [i64, ir.IntType(1)]),
                                            "llvm.cttz.i64")
        return builder.call(fn, [args[0], ir.IntType(1)(1)])
    return types.int64(types.int64), codegen


@njit(cache=True, error_model="numpy", inline="always")
def _origin(o, inv):
    """``(near, far)`` float32 origins: rounded up for near distances along a positive axis, down for far."""
    if inv >= 0.0:
        return blas._up32(o), blas._down32(o)
    return blas._down32(o), blas._up32(o)


@njit(cache=True, error_model="numpy", inline="always")
def ray8(ox, oy, oz, dx, dy, dz):
    """Per-ray constants of :func:`slab8`: near and far origins, inverse direction and times :data:`FAR`
    (float32), near-plane offsets."""
    ix = 1.0 / dx
    iy = 1.0 / dy
    iz = 1.0 / dz
    onx, ofx = _origin(ox, ix)
    ony, ofy = _origin(oy, iy)
    onz, ofz = _origin(oz, iz)
    return (onx, ony, onz, ofx, ofy, ofz, np.float32(ix), np.float32(iy), np.float32(iz), np.float32(ix * FAR),
            np.float32(iy * FAR), np.float32(iz * FAR), 0 if ix >= 0.0 else 3, 1 if iy >= 0.0 else 4,
            2 if iz >= 0.0 else 5)


@njit(cache=True, error_model="numpy", inline="always")
def descend8(ni, r, m, tbuf, stack, tstack, sp):
    """``(ref, sp)``: the nearest child of row ``r`` among the hits ``m`` (a mask, not 0), the others pushed."""
    c = lowest_bit(m)
    m &= m - 1
    ref = np.int64(ni[r + 48 + c])
    tn = tbuf[c]
    while m != 0:
        c = lowest_bit(m)
        m &= m - 1
        t2 = tbuf[c]
        r2 = np.int64(ni[r + 48 + c])
        if t2 < tn:
            stack[sp] = ref
            tstack[sp] = tn
            ref = r2
            tn = t2
        else:
            stack[sp] = r2
            tstack[sp] = t2
        sp += 1
    return ref, sp


@njit(cache=True, error_model="numpy", _nrt=False)
def walk8(nf, ni, tri, ox, oy, oz, dx, dy, dz, stack, tstack, tbuf):
    """Closest-hit distance along the ray through the 8-wide rows (nearest child first)."""
    kx, ky, kz, sx, sy, sz = ray_setup(dx, dy, dz)
    onx, ony, onz, ofx, ofy, ofz, fx, fy, fz, fxe, fye, fze, xl, yl, zl = ray8(ox, oy, oz, dx, dy, dz)
    best_t = np.inf
    sp = 0
    ref = 0
    while True:
        if ref >= 0:
            r = 64 * ref
            m = slab8(nf, r, onx, ony, onz, ofx, ofy, ofz, fx, fy, fz, fxe, fye, fze, xl, yl, zl,
                      blas._up32(best_t), tbuf)
            if m != 0:
                ref, sp = descend8(ni, r, m, tbuf, stack, tstack, sp)
                if ref >= 0:
                    prefetch(nf, 64 * ref)
                else:
                    prefetch(tri, 9 * ((-ref - 1) >> 4))
                continue
        else:
            x = -ref - 1
            for j in range(x >> 4, (x >> 4) + (x & 15)):
                hit, t, _, _ = intersect_triangle(tri, j, ox, oy, oz, kx, ky, kz, sx, sy, sz, best_t)
                if hit:
                    best_t = t
        ref, sp = pop_nearer(stack, tstack, sp, 0, best_t)
        if ref == MISS:
            return best_t


@njit(cache=True, error_model="numpy", _nrt=False)
def rays8(nf, ni, tri, o, d, out, stack, tstack, tbuf):
    for i in range(o.shape[0]):
        out[i] = walk8(nf, ni, tri, o[i, 0], o[i, 1], o[i, 2], d[i, 0], d[i, 1], d[i, 2], stack, tstack, tbuf)


@njit(cache=True, error_model="numpy", _nrt=False)
def rays4(bf, bi, tri, o, d, out, stack, tstack):
    for i in range(o.shape[0]):
        out[i] = traverse_rows(bf, bi, tri, 0, 0, o[i, 0], o[i, 1], o[i, 2], d[i, 0], d[i, 1], d[i, 2], np.inf,
                               False, stack, tstack)[1]


@njit(cache=True, error_model="numpy", _nrt=False)
def walk8_top(sa, nf, ni, ox, oy, oz, dx, dy, dz, stack, tstack, tbuf, bstack, btstack):
    """Closest-hit distance through an 8-wide top level over ``sa``'s instances (leaves: positions in
    ``sa.top_items``), each instance's bottom level walked as today (:mod:`tracer.kinds.dispatch`)."""
    onx, ony, onz, ofx, ofy, ofz, fx, fy, fz, fxe, fye, fze, xl, yl, zl = ray8(ox, oy, oz, dx, dy, dz)
    best_t = np.inf
    m_ = sa.object_from_world
    sp = 0
    ref = 0
    while True:
        if ref >= 0:
            r = 64 * ref
            m = slab8(nf, r, onx, ony, onz, ofx, ofy, ofz, fx, fy, fz, fxe, fye, fze, xl, yl, zl,
                      blas._up32(best_t), tbuf)
            if m != 0:
                ref, sp = descend8(ni, r, m, tbuf, stack, tstack, sp)
                if ref >= 0:
                    prefetch(nf, 64 * ref)
                continue
        else:
            x = -ref - 1
            for q in range(x >> 4, (x >> 4) + (x & 15)):
                inst = sa.top_items[q]
                rox, roy, roz, rdx, rdy, rdz = _to_object(m_, inst, ox, oy, oz, dx, dy, dz)
                hit, t, _, _, _ = dispatch.intersect_solid(sa, inst, rox, roy, roz, rdx, rdy, rdz, best_t, False,
                                                           bstack, btstack)
                if hit:
                    best_t = t
        ref, sp = pop_nearer(stack, tstack, sp, 0, best_t)
        if ref == MISS:
            return best_t


@njit(cache=True, error_model="numpy", _nrt=False)
def rays8_top(sa, nf, ni, o, d, out, stack, tstack, tbuf, bstack, btstack):
    for i in range(o.shape[0]):
        out[i] = walk8_top(sa, nf, ni, o[i, 0], o[i, 1], o[i, 2], d[i, 0], d[i, 1], d[i, 2], stack, tstack, tbuf,
                           bstack, btstack)


@njit(cache=True, error_model="numpy", _nrt=False)
def rays4_top(sa, o, d, out, bstack, btstack):
    for i in range(o.shape[0]):
        out[i] = _closest(sa, o[i, 0], o[i, 1], o[i, 2], d[i, 0], d[i, 1], d[i, 2], np.inf, False, bstack, btstack)[0]


def rows8_of(boxes: np.ndarray, refs: np.ndarray) -> np.ndarray:
    """8-wide rows (64-byte aligned) of one tree's binary child-box rows (:func:`tracer.blas.collapse`)."""
    wb, wr = widen8(boxes, refs)
    rows8 = blas.aligned_rows(4 * len(wb)).reshape(-1, 64)
    pack8(wb, wr, rows8, rows8.view(np.int32))
    return rows8


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


def time_top(scene, o: np.ndarray, d: np.ndarray) -> dict:
    """Today's two-level walk against one whose top level is 8-wide (bottom levels as today), alternating."""
    sa = scene.arrays()
    binary = scene._levels["top"].binary
    rows8 = rows8_of(binary[:, :12].astype(np.float64), binary.view(np.int32)[:, 12:14].astype(np.int64))
    nf, ni = rows8.reshape(-1), rows8.view(np.int32).reshape(-1)
    stack, tstack, tbuf = np.empty(1024, np.int64), np.empty(1024), np.empty(WIDTH, np.float32)
    bstack, btstack = new_stacks()
    t4, t8 = np.empty(len(o)), np.empty(len(o))
    rays4_top(sa, o[:10], d[:10], t4, bstack, btstack)   # compile or load outside the timing
    rays8_top(sa, nf, ni, o[:10], d[:10], t8, stack, tstack, tbuf, bstack, btstack)
    res = alternate(lambda: rays4_top(sa, o, d, t4, bstack, btstack),
                    lambda: rays8_top(sa, nf, ni, o, d, t8, stack, tstack, tbuf, bstack, btstack), len(o))
    return {**res, "top_rows8": len(rows8), "same_hits": bool(np.array_equal(t4, t8))}


def layouts(tri_v: np.ndarray) -> dict:
    """Both layouts of one BVH over ``tri_v`` (m, 9), and the triangles in leaf order."""
    order, nb, na, nn, nc = blas.build_meshes(tri_v, np.array([0, len(tri_v)]), 4, 1.0)
    boxes, refs, row_cnt = blas.collapse(nb, na, nn, np.zeros(1, np.int64), nc)
    wide4, _, _ = blas.pack_wide(boxes, refs, row_cnt)
    return {"rows4": wide4, "rows8": rows8_of(boxes, refs), "tri": blas.leaf_order_f32(tri_v, order)}


def time_pair(lay: dict, o: np.ndarray, d: np.ndarray) -> dict:
    """Both walks over the same rays in alternating rounds: median rates, speed-up, and whether the hits agree."""
    r4, r8, tri = lay["rows4"], lay["rows8"], lay["tri"]
    stack, tstack, tbuf = np.empty(1024, np.int64), np.empty(1024), np.empty(WIDTH, np.float32)
    t4, t8 = np.empty(len(o)), np.empty(len(o))
    b4, i4 = r4.reshape(-1), r4.view(np.int32).reshape(-1)
    b8, i8 = r8.reshape(-1), r8.view(np.int32).reshape(-1)
    rays4(b4, i4, tri, o[:10], d[:10], t4, stack, tstack)   # compile or load outside the timing
    rays8(b8, i8, tri, o[:10], d[:10], t8, stack, tstack, tbuf)
    res = alternate(lambda: rays4(b4, i4, tri, o, d, t4, stack, tstack),
                    lambda: rays8(b8, i8, tri, o, d, t8, stack, tstack, tbuf), len(o))
    return {**res, "same_hits": bool(np.array_equal(t4, t8))}


def probe(name: str) -> dict:
    out: dict = {"scene": name}
    lay = None
    for kind in ("camera", "incoherent"):
        scene, o, d = scene_and_rays(name, kind)
        if name == "scene3":   # two levels: only the top level 8-wide
            r = out[kind] = time_top(scene, o, d)
        else:
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
    names = sys.argv[1:] or ["mesh", "flat3", "scene3"]
    res = {"rounds": ROUNDS, "scenes": [probe(n) for n in names]}
    path = Path(__file__).resolve().parent / "results" / "wide8_probe.json"
    path.write_text(json.dumps(res, indent=1))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
