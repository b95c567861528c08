"""8-wide float32 rows: the solid top level's layout.

A camera ray in the paper's scene 3 visited about 25 top-level rows of the 4-wide layout the bottom levels
use (:func:`tracer.accel.rows4.pack_wide`), each a 4-lane float64 test of 8-bit quantised boxes, and that was most
of its instructions. Here a row holds eight unquantised float32 boxes, tested in one 8-lane float32 vector
(:func:`slab8`), as Embree's BVH8 nodes are: fewer rows per ray (19 where a ray meets no instance's box
early) and no dequantising. Measured on scene 3, one thread: camera rays 1.29x faster, incoherent rays
(:mod:`tracer.accel.lanes`) 1.10x; instructions per ray 28 % / 24 % fewer. The bottom levels stay 4-wide: in the
lanes, 8-wide bottom levels were slower (branch ``wide8``) and would take about three times the memory.

Layout: row ``w`` is 64 float32 values (256 bytes, 64-byte aligned): the planes ``8 a + c`` (``a`` =
xmin, ymin, zmin, xmax, ymax, zmax; ``c`` the slot), each the binary row's float32 plane (already rounded
outward, :func:`tracer.accel.rows4.pack_rows`), then the eight references (int32 view, columns 48-55) as in
:func:`tracer.accel.blas.collapse` with rows now 8-wide rows. An empty slot has an inverted box and
reference -1.

The float32 slab test is conservative at any coordinate magnitude: pbrt's form ``(p - o) inv``, whose
rounding is relative to the distance, with far distances scaled by :data:`FAR32`; the origin rounded
towards the near plane for near distances and away from it for far ones (so rounding the origin only
grows a box); ``t_max`` rounded up; the entry distances it reports scaled down by :data:`NEAR32`, so a
pending row is never culled by a hit nearer than its true entry.
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from tracer.accel.blas import STACK_SIZE, box_area
from tracer.accel.rows4 import aligned_rows, down32, up32
from tracer.jit import njit

WIDTH = 8
#: float32 values per row (48 planes, 8 references, 8 unused): four cache lines
ROW = 64
#: entries a walk may keep pending: up to ``WIDTH - 1`` per row on its path, and a path visits at most
#: one row per binary level (fewer than STACK_SIZE: the build halves ranges beyond MAX_SAH_DEPTH)
STACK = (WIDTH - 1) * STACK_SIZE
#: float32 rounding allowance on far distances: ``1 + 2 gamma(3)`` of float32, plus one float32 ulp for
#: rounding the inverse direction times it
FAR32 = 1.0 + 2.0 * (3 * 2.0**-24 / (1 - 3 * 2.0**-24)) + 2.0**-22
#: entry distances are at most three float32 roundings (``3 u``) above the exact ones: scaled by this
#: (``1 - 8 u``, exact in float64) they are below
NEAR32 = 1.0 - 2.0**-21
_FLT_MAX = 3.4028234663852886e38


@njit(cache=True, error_model="numpy")
def widen8(boxes, refs):
    """Collapse one tree's binary child-box rows (:func:`tracer.accel.blas.collapse`) into 8-wide rows.

    A row starts from a binary row's two children and opens the interior child of largest surface area
    (the likeliest to be entered) into its two children, until it holds eight children or only leaves,
    as Embree builds its BVH8 nodes.

    Returns ``wboxes`` (W, 48) float64 planes (``8 a + c``), ``wrefs`` (W, 8) int64, ``wsrc`` (W, 8)
    int64: the binary row and slot each box came from (``2 row + slot``, -1 for an empty slot), for
    refits (:func:`refit8`), and ``depth``: the most rows on one path.
    """
    total = max(boxes.shape[0], 1)
    wboxes = np.empty((total, 6 * WIDTH))
    wrefs = np.empty((total, WIDTH), np.int64)
    wsrc = np.empty((total, WIDTH), np.int64)
    queue = np.zeros(total + 1, np.int64)
    level = np.ones(total + 1, np.int64)
    src = np.empty(WIDTH, np.int64)
    nw = 1 if boxes.shape[0] > 0 else 0
    depth = nw
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
                    o = 6 * (s & 1)
                    b = s >> 1
                    area = box_area(boxes[b, o], boxes[b, o + 1], boxes[b, o + 2], boxes[b, o + 3], boxes[b, o + 4],
                                 boxes[b, o + 5])
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
                wsrc[k, slot] = s
                ref = refs[s >> 1, s & 1]
                if ref >= 0:
                    queue[nw] = ref
                    level[nw] = level[k] + 1
                    depth = max(depth, level[nw])
                    ref = nw
                    nw += 1
                wrefs[k, slot] = ref
            else:
                for a in range(3):
                    wboxes[k, WIDTH * a + slot] = np.inf
                    wboxes[k, WIDTH * (a + 3) + slot] = -np.inf
                wrefs[k, slot] = -1
                wsrc[k, slot] = -1
        k += 1
    return wboxes[:nw], wrefs[:nw], wsrc[:nw], depth


@njit(cache=True, error_model="numpy")
def refit8(rows, wsrc, binary, wrows):
    """Copy into the 8-wide rows ``wrows`` the current planes of the binary rows ``binary`` ((R, 16) float32,
    :func:`tracer.accel.rows4.pack_rows`) their boxes came from: how a refit of the binary top level reaches them."""
    for k in range(wrows.shape[0]):
        w = wrows[k]
        for c in range(WIDTH):
            s = wsrc[w, c]
            if s >= 0:
                for a in range(6):
                    rows[w, WIDTH * a + c] = binary[s >> 1, 6 * (s & 1) + a]


def pack8(binary: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """8-wide rows of the binary child-box rows ``binary`` ((R, 16) float32, one tree): ``(rows, wsrc)``,
    ``rows`` (W, :data:`ROW`) float32 (int32 view for the references), 64-byte aligned."""
    boxes = binary[:, :12].astype(np.float64)
    wboxes, wrefs, wsrc, depth = widen8(boxes, binary.view(np.int32)[:, 12:14].astype(np.int64))
    if (WIDTH - 1) * depth > STACK:
        raise AssertionError(f"an 8-wide top level {depth} rows deep would overflow the traversal stack")
    rows = aligned_rows(4 * len(wboxes)).reshape(-1, ROW)
    rows[:, :6 * WIDTH] = wboxes   # float32 values already: exact
    rows.view(np.int32)[:, 6 * WIDTH:7 * WIDTH] = wrefs
    rows.view(np.int32)[:, 7 * WIDTH:] = 0
    return rows, wsrc


@intrinsic
def slab8(typingctx, bf, r, onx, ony, onz, ofx, ofy, ofz, ix, iy, iz, ixe, iye, ize, xl, yl, zl, t_max, tstack, tb):
    """Slab test of the eight boxes of the row at ``bf[r]`` in one 8-lane float32 vector pass. Returns the
    mask of the boxes the segment ``0 <= t <= t_max`` meets (bit ``c`` for slot ``c``) and stores their
    entry distances, times :data:`NEAR32`, as float64 to ``tstack[tb : tb + 8]``.

    The per-ray constants come from :func:`ray8` (float32 values passed as float64; ``t_max`` too, rounded
    up). A NaN slab (origin on the plane of an axis the ray is parallel to) is ignored, as in
    :func:`tracer.accel.wide.slab`.
    """
    sig = types.int64(bf, types.int64, *(types.float64,) * 12, types.int64, types.int64, types.int64,
                      types.float64, tstack, types.int64)

    def codegen(context, builder, sig, args):
        row = builder.gep(context.make_array(sig.args[0])(context, builder, args[0]).data, [args[1]], inbounds=True)
        out = builder.gep(context.make_array(sig.args[18])(context, builder, args[18]).data, [args[19]],
                          inbounds=True)
        onx, ony, onz, ofx, ofy, ofz, ix, iy, iz, ixe, iye, ize, xl, yl, zl, t_max = args[2:18]
        flt = ir.FloatType()
        i32 = ir.IntType(32)
        i64 = ir.IntType(64)
        v8 = ir.VectorType(flt, WIDTH)
        d8 = ir.VectorType(ir.DoubleType(), WIDTH)
        undef = ir.Constant(v8, ir.Undefined)
        zeros = ir.Constant(ir.VectorType(i32, WIDTH), [0] * WIDTH)

        def splat(x):   # a float32 value held in a float64: exact
            return builder.shuffle_vector(builder.insert_element(undef, builder.fptrunc(x, flt), i32(0)), undef, zeros)

        def plane(p):
            ptr = builder.gep(row, [builder.mul(p, i64(WIDTH))], inbounds=True)
            return builder.load(builder.bitcast(ptr, v8.as_pointer()), align=4)

        tn = ir.Constant(v8, [0.0] * WIDTH)
        tf = splat(t_max)
        for a, (near, on, of, inv, inve) in enumerate(((xl, onx, ofx, ix, ixe), (yl, ony, ofy, iy, iye),
                                                      (zl, onz, ofz, iz, ize))):
            t0 = builder.fmul(builder.fsub(plane(near), splat(on)), splat(inv))
            t1 = builder.fmul(builder.fsub(plane(builder.sub(i64(2 * a + 3), near)), splat(of)), splat(inve))
            # max(tn, t0) / min(tf, t1) keeping tn / tf when t0 / t1 is NaN, as slab() does
            tn = builder.select(builder.fcmp_ordered(">", t0, tn), t0, tn)
            tf = builder.select(builder.fcmp_ordered("<", t1, tf), t1, tf)
        near = builder.fmul(builder.fpext(tn, d8), ir.Constant(d8, [NEAR32] * WIDTH))
        builder.store(near, builder.bitcast(out, d8.as_pointer()), align=8)
        hit = builder.fcmp_ordered("<=", tn, tf)
        return builder.zext(builder.bitcast(hit, ir.IntType(WIDTH)), i64)
    return sig, codegen


@intrinsic
def lowest_bit(typingctx, x):
    """Index of the lowest set bit of ``x`` (> 0): one ``tzcnt``."""
    def codegen(context, builder, sig, args):
        i64 = ir.IntType(64)
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(i64, [i64, ir.IntType(1)]),
                                            "llvm.cttz.i64")
        return builder.call(fn, [args[0], ir.IntType(1)(1)])
    return types.int64(types.int64), codegen


@njit(cache=True, error_model="numpy", inline="always")
def descend8(bi, r, hits, stack, tstack, tb, sp):
    """``(ref, sp)``: where a walk goes from row ``r`` whose boxes ``hits`` (a mask, not 0) it met at the
    distances :func:`slab8` left at ``tstack[tb:]``: the nearest child; the others are pushed."""
    c = lowest_bit(hits)
    hits &= hits - 1
    ref = np.int64(bi[r + 6 * WIDTH + c])
    tn = tstack[tb + c]
    while hits != 0:
        c = lowest_bit(hits)
        hits &= hits - 1
        t = tstack[tb + c]
        other = np.int64(bi[r + 6 * WIDTH + c])
        if t < tn:
            stack[sp] = ref
            tstack[sp] = tn
            ref = other
            tn = t
        else:
            stack[sp] = other
            tstack[sp] = t
        sp += 1
    return ref, sp


@njit(cache=True, error_model="numpy", inline="always")
def _origin(o, inv):
    """The origin coordinate rounded to float32 ``(for near distances, for far ones)``: towards the near
    plane and away from it. Clamped first, so an origin beyond float32's range still rounds the right way."""
    lo = np.float64(down32(min(o, _FLT_MAX)))
    hi = np.float64(up32(max(o, -_FLT_MAX)))
    pos = inv >= 0.0
    return (hi if pos else lo), (lo if pos else hi)


@njit(cache=True, error_model="numpy", inline="always")
def _far32(inv):
    """``inv`` times :data:`FAR32`, rounded away from zero to float32."""
    x = inv * FAR32
    up = np.float64(up32(x))   # both, then a select: the sign is as good as random
    down = np.float64(down32(x))
    return up if x >= 0.0 else down


@njit(cache=True, error_model="numpy", inline="always")
def ray8(ox, oy, oz, dx, dy, dz):
    """Per-ray constants of :func:`slab8`: ``(onx, ony, onz, ofx, ofy, ofz, ix, iy, iz, ixe, iye, ize,
    xl, yl, zl)``: the origin for near and far distances, the inverse direction and the same times
    :data:`FAR32` (float32 values), the near-plane offsets (0/1/2 or 3/4/5)."""
    ix = 1.0 / dx
    iy = 1.0 / dy
    iz = 1.0 / dz
    onx, ofx = _origin(ox, ix)
    ony, ofy = _origin(oy, iy)
    onz, ofz = _origin(oz, iz)
    return (onx, ony, onz, ofx, ofy, ofz, np.float64(np.float32(ix)), np.float64(np.float32(iy)),
            np.float64(np.float32(iz)), _far32(ix), _far32(iy), _far32(iz),
            0 if ix >= 0.0 else 3, 1 if iy >= 0.0 else 4, 2 if iz >= 0.0 else 5)
