"""The walk of one ray through a mesh's bottom level: 4-wide quantised rows (:func:`tracer.accel.rows4.pack_wide`).

The slab tests of a wide row's four boxes (scalar :func:`slab`, vector :func:`slab4`, sorted
:func:`slab4_sorted`), the near-first ordering and the traversal stack (:func:`order4`, :func:`push3`,
:func:`pop_nearer`), the cache hint :func:`prefetch`, and the walk itself (:func:`walk_rows`,
:func:`traverse_rows`). The mesh kind (:mod:`tracer.kinds.mesh`) enters a geometry through
:func:`traverse_rows`; the two-level walks (:mod:`tracer.accel.traverse`, :mod:`tracer.accel.lanes`) use the
pieces directly. Results are in object space; a hit's ``slot`` is the triangle's row in ``sa.tri_v``.
"""

from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from tracer.accel import rows8
from tracer.accel.triangle import intersect_triangle, origin_setup, ray_setup
from tracer.jit import njit

#: float64 rounding allowance on the slab test's far distance (pbrt: 1 + 2 gamma(3))
BOX_EPS = 1.0 + 8.0 * 1.1102230246251565e-16


@intrinsic
def prefetch(typingctx, arr, idx):
    """Hint the CPU to fetch the cache line of ``arr[idx]`` (``llvm.prefetch``, read, keep in all levels).

    Incoherent rays through a large BVH wait on memory for almost every row (one cache miss per row);
    asking for the next row (or leaf) as soon as it is chosen overlaps its latency with the sorting
    and stack work.
    Never faults (an address past the array is a harmless hint) and changes no result. Compiled for a CUDA
    card (an ``nvptx`` module) it emits nothing: NVVM leaves ``llvm.prefetch`` as an external function, which
    ptxas refuses (seen on an H200, issue 40), and a card hides memory latency with other warps instead.
    """
    def codegen(context, builder, sig, args):
        if builder.module.triple.startswith("nvptx"):   # on a GPU: no hint (ptxas rejects llvm.prefetch)
            return context.get_dummy_value()
        ary = context.make_array(sig.args[0])(context, builder, args[0])
        ptr = builder.gep(ary.data, [args[1]])
        i32 = ir.IntType(32)
        fnty = ir.FunctionType(ir.VoidType(), [cgutils.voidptr_t, i32, i32, i32])
        fn = cgutils.get_or_insert_function(builder.module, fnty, "llvm.prefetch.p0")
        builder.call(fn, [builder.bitcast(ptr, cgutils.voidptr_t), i32(0), i32(3), i32(1)])
        return context.get_dummy_value()
    return types.void(arr, types.int64), codegen


def _slab_lanes(context, builder, sig, args):
    """LLVM IR of the slab test of a wide row's four boxes: their entry distances, a 4-lane vector.

    Each plane of four 8-bit grid steps is loaded at once and dequantised exactly (``origin + q
    scale``), then the same operations as :func:`slab` follow lane by lane: NaN slabs are ignored, the
    far distances are enlarged by :data:`BOX_EPS`; a box the segment ``0 <= t <= t_max`` misses gets
    ``inf``. (numba leaves four scalar slab tests unvectorised; this is the vector form.)
    """
    ary = context.make_array(sig.args[0])(context, builder, args[0])
    _, r, ox, oy, oz, ix, iy, iz, ixe, iye, ize, xl, yl, zl, t_max = args
    dbl = ir.DoubleType()
    i32 = ir.IntType(32)
    i64 = ir.IntType(64)
    d4 = ir.VectorType(dbl, 4)
    undef = ir.Constant(d4, ir.Undefined)
    lanes0 = ir.Constant(ir.VectorType(i32, 4), [0, 0, 0, 0])
    row = builder.gep(ary.data, [r], inbounds=True)
    qbase = builder.gep(builder.bitcast(row, cgutils.voidptr_t), [i64(24)], inbounds=True)

    def splat(x):
        return builder.shuffle_vector(builder.insert_element(undef, x, i32(0)), undef, lanes0)

    fma = cgutils.get_or_insert_function(builder.module, ir.FunctionType(d4, [d4, d4, d4]), "llvm.fma.v4f64")

    def plane(p, origin, scale):
        ptr = builder.bitcast(builder.gep(qbase, [builder.mul(p, i64(4))], inbounds=True),
                              ir.VectorType(ir.IntType(8), 4).as_pointer())
        q = builder.uitofp(builder.load(ptr, align=1), d4)
        return builder.call(fma, [q, scale, origin])   # exact either way (tracer.accel.rows4._quantize): one op

    # origin and scale: two 4-float loads widened at once, each value then splat from its lane
    f4p = ir.VectorType(ir.FloatType(), 4).as_pointer()
    head = builder.fpext(builder.load(builder.bitcast(row, f4p), align=4), d4)                # ox oy oz sx
    tail = builder.fpext(builder.load(builder.bitcast(builder.gep(row, [i64(2)], inbounds=True), f4p),
                                      align=4), d4)                                          # oz sx sy sz

    def lane(v, c):
        return builder.shuffle_vector(v, undef, ir.Constant(ir.VectorType(i32, 4), [c] * 4))

    tn = splat(dbl(0.0))
    tf = splat(t_max)
    for a, (near, o, inv, inve) in enumerate(((xl, ox, ix, ixe), (yl, oy, iy, iye), (zl, oz, iz, ize))):
        far = builder.sub(i64(2 * a + 3), near)
        origin = lane(head, a)
        scale = lane(head, 3) if a == 0 else lane(tail, a + 1)
        so = splat(o)
        t0 = builder.fmul(builder.fsub(plane(near, origin, scale), so), splat(inv))
        t1 = builder.fmul(builder.fsub(plane(far, origin, scale), so), splat(inve))
        # max(tn, t0) / min(tf, t1) keeping tn / tf when t0 / t1 is NaN, as slab() does
        tn = builder.select(builder.fcmp_ordered(">", t0, tn), t0, tn)
        tf = builder.select(builder.fcmp_ordered("<", t1, tf), t1, tf)
    return builder.select(builder.fcmp_ordered("<=", tn, tf), tn, ir.Constant(d4, [math.inf] * 4))


_SLAB_ARGS = (types.int64,) + (types.float64,) * 9 + (types.int64,) * 3 + (types.float64,)


@intrinsic
def slab4(typingctx, bf, r, ox, oy, oz, ix, iy, iz, ixe, iye, ize, xl, yl, zl, t_max):
    """Slab test of the four child boxes of the wide row at ``bf[r]`` (:func:`tracer.accel.rows4.pack_wide`)
    in one pass of 4-lane double-precision vector code (:func:`_slab_lanes`).

    Arguments as for :func:`slab` (``xl`` etc.: the near plane, 0/1/2 or 3/4/5). Returns the four
    entry distances, ``inf`` for a box the segment ``0 <= t <= t_max`` misses.
    """
    sig = types.UniTuple(types.float64, 4)(bf, *_SLAB_ARGS)

    def codegen(context, builder, sig, args):
        res = _slab_lanes(context, builder, sig, args)
        vals = [builder.extract_element(res, ir.IntType(32)(c)) for c in range(4)]
        return context.make_tuple(builder, sig.return_type, vals)
    return sig, codegen


@intrinsic
def slab4_sorted(typingctx, bf, r, ox, oy, oz, ix, iy, iz, ixe, iye, ize, xl, yl, zl, t_max):
    """:func:`slab4` with the hits sorted nearest first in the vector registers, without a branch.

    The entry distances of the boxes hit are finite and non-negative, so their bit patterns order as
    integers: the child's slot replaces their two lowest bits, misses become ``inf``, and a
    5-comparator network sorts these four keys. The distances returned have those two bits cleared:
    at most 3 ulp below the exact entry, so culling a pending box beyond the best hit stays
    conservative.

    Returns ``(n, t1, t2, t3, c0, c1, c2, c3)``: the number of boxes hit, the entry distances of the
    second to fourth nearest (``inf`` past ``n``) and the slots (0-3) of all four, nearest first
    (those past ``n`` are meaningless). For :mod:`tracer.accel.lanes`, whose interleaved rays defeat branch
    prediction; a single ray's walk is faster with :func:`order4`'s branches, which the CPU predicts
    and runs ahead of (10 % on coherent rays).
    """
    i8 = types.int64
    f8 = types.float64
    sig = types.Tuple((i8, f8, f8, f8, i8, i8, i8, i8))(bf, *_SLAB_ARGS)

    def codegen(context, builder, sig, args):
        res = _slab_lanes(context, builder, sig, args)
        i32 = ir.IntType(32)
        i64 = ir.IntType(64)
        d4 = ir.VectorType(ir.DoubleType(), 4)
        l4 = ir.VectorType(i64, 4)
        inf = ir.Constant(d4, [math.inf] * 4)
        hit = builder.fcmp_ordered("<", res, inf)   # (an entry at inf would make a NaN key)

        def lanes(*ix):
            return ir.Constant(ir.VectorType(i32, 4), list(ix))

        ctpop = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.IntType(4), [ir.IntType(4)]),
                                               "llvm.ctpop.i4")
        n = builder.zext(builder.call(ctpop, [builder.bitcast(hit, ir.IntType(4))]), i64)
        bits = builder.and_(builder.bitcast(res, l4), ir.Constant(l4, [-4] * 4))
        v = builder.select(hit, builder.bitcast(builder.or_(bits, ir.Constant(l4, [0, 1, 2, 3])), d4), inf)
        # (0,1)(2,3), (0,2)(1,3), (1,2): each a swap, a min, a max and a blend of two vectors
        undef = ir.Constant(d4, ir.Undefined)
        for swap, blend in (((1, 0, 3, 2), (0, 5, 2, 7)), ((2, 3, 0, 1), (0, 1, 6, 7)), ((0, 2, 1, 3), (0, 1, 6, 3))):
            w = builder.shuffle_vector(v, undef, lanes(*swap))
            lt = builder.fcmp_ordered("<", v, w)
            v = builder.shuffle_vector(builder.select(lt, v, w), builder.select(lt, w, v), lanes(*blend))
        keys = builder.bitcast(v, l4)
        slots = builder.and_(keys, ir.Constant(l4, [3] * 4))
        t = builder.bitcast(builder.and_(keys, ir.Constant(l4, [-4] * 4)), d4)   # the slot cleared: <= the distance
        vals = ([n] + [builder.extract_element(t, i32(c)) for c in (1, 2, 3)]
                + [builder.extract_element(slots, i32(c)) for c in range(4)])
        return context.make_tuple(builder, sig.return_type, vals)
    return sig, codegen


#: where a bottom level's entries start in the traversal stacks (the 8-wide top level's lie below)
STACK_BASE = rows8.STACK
#: :func:`order4`'s nearest reference when no box is hit, :func:`pop_nearer`'s when no entry is left
#: (references are >= -(16 * 2**27))
MISS = np.int64(-(1 << 62))


@njit(cache=True, error_model="numpy", inline="always")
def _order(ta, ra, tb, rb):
    """Compare-exchange of a sorting network: the nearer pair first."""
    s = tb < ta
    return (tb if s else ta), (rb if s else ra), (ta if s else tb), (ra if s else rb)


@njit(cache=True, error_model="numpy", inline="always")
def order4(t0, t1, t2, t3, bi, r):
    """Sort the four entry distances of wide row ``r`` (from :func:`slab4`) with their references:
    ``(nearest, r1, r2, r3, t1, t2, t3)``, nearest :data:`MISS` when no box is hit. (LLVM compiles
    the network to branches, which the CPU predicts well along one ray's walk.)"""
    u = np.uint64(r + 12)   # an unsigned index: no wraparound check for negative values
    r0 = np.int64(bi[u])
    r1 = np.int64(bi[u + np.uint64(1)])
    r2 = np.int64(bi[u + np.uint64(2)])
    r3 = np.int64(bi[u + np.uint64(3)])
    t0, r0, t1, r1, t2, r2, t3, r3 = sort4(t0, r0, t1, r1, t2, r2, t3, r3)
    return (r0 if t0 < np.inf else MISS), r1, r2, r3, t1, t2, t3


@njit(cache=True, error_model="numpy", inline="always")
def sort4(t0, r0, t1, r1, t2, r2, t3, r3):
    """Four (distance, reference) pairs, nearest first: a 5-comparator network."""
    t0, r0, t1, r1 = _order(t0, r0, t1, r1)
    t2, r2, t3, r3 = _order(t2, r2, t3, r3)
    t0, r0, t2, r2 = _order(t0, r0, t2, r2)
    t1, r1, t3, r3 = _order(t1, r1, t3, r3)
    t1, r1, t2, r2 = _order(t1, r1, t2, r2)
    return t0, r0, t1, r1, t2, r2, t3, r3


@njit(cache=True, error_model="numpy", inline="always")
def pop_nearer(stack, tstack, sp, base, best_t):
    """``(ref, sp)``: the last pending entry above ``base`` that starts no farther than ``best_t``
    (entries beyond it are dropped), or :data:`MISS` when none is left."""
    while sp > base:
        sp -= 1
        if tstack[np.uint64(sp)] <= best_t:   # (unsigned: no wraparound check)
            return stack[np.uint64(sp)], sp
    return MISS, sp


@njit(cache=True, error_model="numpy", inline="always")
def push3(stack, tstack, sp, r1, r2, r3, t1, t2, t3):
    """Push the farther hits of a sorted wide row, farthest first, without branches (the entries
    past ``sp`` are scratch: all three are written, the hits kept). Returns the new ``sp``."""
    u = np.uint64(sp)   # an unsigned index: no wraparound check for negative values
    stack[u] = r3
    tstack[u] = t3
    u += np.uint64(t3 < np.inf)
    stack[u] = r2
    tstack[u] = t2
    u += np.uint64(t2 < np.inf)
    stack[u] = r1
    tstack[u] = t1
    u += np.uint64(t1 < np.inf)
    return np.int64(u)


@njit(cache=True, error_model="numpy", inline="always")
def slab(bf, b, ox, oy, oz, ix, iy, iz, ixe, iye, ize, xl, yl, zl, t_max):
    """Slab test of the box ``bf[b : b+6]`` (xmin, ymin, zmin, xmax, ymax, zmax).

    ``ix`` etc. are the inverse direction, ``ixe`` the same times :data:`BOX_EPS` (the far distance is
    enlarged so float64 rounding never culls a box the ray touches), ``xl`` etc. the near-plane
    offsets (0/1/2 for a positive direction, 3/4/5 for a negative one). Returns ``(hit, t_near)``
    for ``0 <= t <= t_max``. A NaN slab (origin on the plane of an axis the ray is parallel to) is
    ignored: numba's ``max(a, b)``/``min(a, b)`` return ``a`` when ``b`` is NaN (and compile to
    branch-free selects): conservative.
    """
    tn = 0.0
    tf = t_max
    t0 = (bf[b + xl] - ox) * ix
    t1 = (bf[b + 3 - xl] - ox) * ixe
    tn = max(tn, t0)
    tf = min(tf, t1)
    t0 = (bf[b + yl] - oy) * iy
    t1 = (bf[b + 5 - yl] - oy) * iye
    tn = max(tn, t0)
    tf = min(tf, t1)
    t0 = (bf[b + zl] - oz) * iz
    t1 = (bf[b + 7 - zl] - oz) * ize
    tn = max(tn, t0)
    tf = min(tf, t1)
    return tn <= tf, tn


@njit(cache=True, error_model="numpy", inline="always")
def ray_inverse(dx, dy, dz):
    """Per-ray constants of :func:`slab`: ``(ix, iy, iz, ixe, iye, ize, xl, yl, zl)``."""
    ix = 1.0 / dx
    iy = 1.0 / dy
    iz = 1.0 / dz
    xl = 0 if ix >= 0.0 else 3
    yl = 1 if iy >= 0.0 else 4
    zl = 2 if iz >= 0.0 else 5
    return ix, iy, iz, ix * BOX_EPS, iy * BOX_EPS, iz * BOX_EPS, xl, yl, zl


@njit(cache=True, error_model="numpy", inline="always")
def prefetch_ref(bf, tri, row0, tri0, ref):
    """Ask for the row, or the leaf's first triangle, that ``ref`` names, as soon as it is chosen."""
    if ref >= 0:
        prefetch(bf, 16 * (row0 + ref))
    else:
        prefetch(tri, 9 * (tri0 + ((-ref - 1) >> 4)))


@njit(cache=True, error_model="numpy", _nrt=False)
def traverse_rows(bf, bi, tri, row0, tri0, ox, oy, oz, dx, dy, dz, t_max, any_hit, stack, tstack):
    """:func:`walk_rows` as a real function, compiled once: inlined into every caller, it made each
    caller's compile longer (transport compiles a variant per effect set)."""
    return walk_rows(bf, bi, tri, row0, tri0, ox, oy, oz, dx, dy, dz, t_max, any_hit, stack, tstack)


@njit(cache=True, error_model="numpy", _nrt=False)
def traverse_from(bf, bi, tri, row0, tri0, ox, oy, oz, dx, dy, dz, t_max, any_hit, stack, tstack, ref0, base):
    """:func:`walk_from` as a real function, compiled once (for :mod:`tracer.accel.packets`)."""
    return walk_from(bf, bi, tri, row0, tri0, ox, oy, oz, dx, dy, dz, t_max, any_hit, stack, tstack, ref0, base)


@njit(cache=True, error_model="numpy", inline="always")
def walk_rows(bf, bi, tri, row0, tri0, ox, oy, oz, dx, dy, dz, t_max, any_hit, stack, tstack):
    """:func:`tracer.kinds.mesh.traverse` on explicit arrays (LLVM optimises the loop better on plain array arguments
    than on fields of the scene tuple), inlined: the batch kernel's walk of one ray enters instances
    through it without a call (:func:`tracer.accel.traverse.walk_scene`), whose argument passing and register
    spills cost 6 % of a camera ray's instructions in the paper's scene 3.

    Wide rows (:func:`tracer.accel.rows4.pack_wide`): the four boxes are tested at once (:func:`slab4`), the
    hits sorted by entry distance with a branch-free network; the nearest is visited next, the
    others pushed farthest first (a pending entry is skipped when it starts beyond the best hit).
    ``stack``, ``tstack``: as from :func:`tracer.accel.traverse.new_stacks`; a bottom level uses the entries
    from :data:`STACK_BASE` on (the top level those below), so no view of the arrays is made per ray.
    """
    return walk_from(bf, bi, tri, row0, tri0, ox, oy, oz, dx, dy, dz, t_max, any_hit, stack, tstack, 0, STACK_BASE)


@njit(cache=True, error_model="numpy", inline="always")
def walk_from(bf, bi, tri, row0, tri0, ox, oy, oz, dx, dy, dz, t_max, any_hit, stack, tstack, ref0, base):
    """:func:`walk_rows` from the row (or leaf) ``ref0`` down, with the stack entries from ``base`` on: a packet
    walk (:mod:`tracer.accel.packets`) hands a ray that left its packet over to it."""
    ix, iy, iz, ixe, iye, ize, xl, yl, zl = ray_inverse(dx, dy, dz)
    kz = -1   # the triangle test's setup, made at the first leaf (most instances entered have none)
    kx = ky = 0
    sx = sy = sz = 0.0
    okx = oky = okz = 0.0
    best_t = t_max
    best = -1
    bu = 0.0
    bv = 0.0
    sp = base
    ref = ref0
    while True:
        if ref >= 0:
            r = 16 * (row0 + ref)
            t0, t1, t2, t3 = slab4(bf, r, ox, oy, oz, ix, iy, iz, ixe, iye, ize, xl, yl, zl, best_t)
            ref, r1, r2, r3, t1, t2, t3 = order4(t0, t1, t2, t3, bi, r)
            if ref != MISS:
                if t1 < np.inf:
                    sp = push3(stack, tstack, sp, r1, r2, r3, t1, t2, t3)
                prefetch_ref(bf, tri, row0, tri0, ref)
                continue
        else:
            if kz < 0:
                kx, ky, kz, sx, sy, sz = ray_setup(dx, dy, dz)
                okx, oky, okz = origin_setup(ox, oy, oz, kx, ky, kz)
            x = -ref - 1
            first = tri0 + (x >> 4)
            for j in range(first, first + (x & 15)):
                hit, t, u, v = intersect_triangle(tri, j, okx, oky, okz, kx, ky, kz, sx, sy, sz, best_t)
                if hit:
                    best_t = t
                    best = j
                    bu = u
                    bv = v
                    if any_hit:
                        return True, best_t, best, bu, bv
        ref, sp = pop_nearer(stack, tstack, sp, base, best_t)
        if ref == MISS:
            break
    return best >= 0, best_t, best, bu, bv
