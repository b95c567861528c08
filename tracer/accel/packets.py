"""Camera rays walked eight at a time: one row's boxes tested against a packet of rays in one vector pass.

A camera's neighbouring rays start at one point and point nearly the same way, so they visit the same
rows, in the same order, down to the same leaves. One ray at a time (:func:`tracer.accel.traverse.walk_scene`),
each pays every row's decoding, sorting and stack work by itself; here eight neighbours share it (Wald,
Slusallek, Benthin and Wagner, "Interactive rendering with coherent ray tracing", 2001): a child box is
decoded once and tested against the eight rays in one 8-lane vector (:func:`packet_slab`), the children
are ordered once, and a stack entry carries the mask of the rays that entered it, so a ray that left
the packet's way costs nothing below. Leaves test each triangle against the rays that reached them,
one by one, with the same watertight test (:func:`tracer.accel.triangle.intersect_triangle`) and the
same slab arithmetic as the single-ray walk, so every ray gets the answer it would get alone.

A packet needs one origin (the batch's coherent blocks have one, :func:`tracer.accel.lanes.is_coherent`)
and its rays' directions of one sign on each axis in the mesh's space; where they differ, its rays are
walked one by one instead. Packets walk a scene of one mesh instance (one large mesh, or a scene flattened
into one); across a top level of many instances the batch walks rays one by one (:func:`packet_block`).
Deeper in a tree, where the packet's rays part ways, a row reached by :data:`SOLO` rays or fewer is left
to them one by one (:func:`tracer.accel.wide.traverse_from`).

Packet state: ``P`` (:data:`NPF`, 8) float64 and ``PI`` (:data:`NPI`, 8) int64, a row per field
(names below), a column per ray.
"""

from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from tracer.accel import rows8, wide
from tracer.accel.traverse import walk_scene
from tracer.accel.triangle import intersect_triangle, origin_setup, ray_setup
from tracer.accel.wide import MISS, pop_nearer, prefetch, push3, sort4
from tracer.jit import njit
from tracer.kinds import mesh

#: rays per packet (one 8-lane vector of float64: two AVX2 registers, one AVX-512)
WIDTH = 8
#: a row reached by this many rays of a packet or fewer is left to them one by one: a packet's row (four boxes, each
#: decoded and tested in eight lanes, the masks reduced) costs several single-ray rows (measured with bench/ab.py,
#: mesh camera rays: 3 and 5 alike within noise, x0.86-0.89 against no packets; handing over only lone rays x0.96)
SOLO = 5

# P rows (float64), one column per ray
DX, DY, DZ = 0, 1, 2            # world direction
IX = 3                          # the object-space slab constants (wide.ray_inverse): ix iy iz, ixe iye ize
TB = 9                          # best hit distance so far (t_max before a hit)
BU, BV = 10, 11                 # its barycentrics
SX, SY, SZ = 12, 13, 14         # triangle shear (tracer.accel.triangle.ray_setup), object space
OKX, OKY, OKZ = 15, 16, 17      # the origin in the triangle test's axis order (origin_setup)
RDX, RDY, RDZ = 18, 19, 20      # the object-space direction
TC = 21                         # columns 0-3: a row's four children's entry distances (scratch)
NPF = 22
# PI rows (int64)
KX, KY, KZ = 0, 1, 2            # triangle axes (object space; KZ < 0: not made yet)
INST, SLOT = 3, 4               # best hit's instance and slot (-1: none)
KC = 5                          # columns 0-3: the four children's stack entries (scratch)
NPI = 6


@intrinsic
def packet_slab(typingctx, P, nx, ny, nz, fx, fy, fz, mask):
    """Slab test of one box against the rays ``mask`` of the packet ``P``: ``(hits, t_near)``.
    ``nx .. nz`` are the box's near planes minus the packet's origin, ``fx .. fz`` its far planes minus the
    origin (near and far chosen by the packet's direction signs). Per ray the arithmetic is
    :func:`tracer.accel.wide.slab`'s: ``(plane - o) * inv``, far distances times :data:`BOX_EPS`, a NaN
    slab ignored, ``0 <= t <= P[TB]``. ``hits``: the rays of ``mask`` that meet the box (bit ``k`` for
    ray ``k``); ``t_near``: the least entry distance among them (``inf`` when none).
    """
    sig = types.Tuple((types.int64, types.float64))(P, *(types.float64,) * 6, types.int64)

    def codegen(context, builder, sig, args):
        dbl = ir.DoubleType()
        i32 = ir.IntType(32)
        i64 = ir.IntType(64)
        d8 = ir.VectorType(dbl, WIDTH)
        undef = ir.Constant(d8, ir.Undefined)
        zeros = ir.Constant(ir.VectorType(i32, WIDTH), [0] * WIDTH)
        data = context.make_array(sig.args[0])(context, builder, args[0]).data

        def field(f):
            ptr = builder.gep(data, [i64(f * WIDTH)], inbounds=True)
            return builder.load(builder.bitcast(ptr, d8.as_pointer()), align=8)

        def splat(x):
            return builder.shuffle_vector(builder.insert_element(undef, x, i32(0)), undef, zeros)

        tn = ir.Constant(d8, [0.0] * WIDTH)
        tf = field(TB)
        for a in range(3):
            near, far = args[1 + a], args[4 + a]
            inv = IX + a
            inve = IX + 3 + a
            t0 = builder.fmul(splat(near), field(inv))
            t1 = builder.fmul(splat(far), field(inve))
            tn = builder.select(builder.fcmp_ordered(">", t0, tn), t0, tn)
            tf = builder.select(builder.fcmp_ordered("<", t1, tf), t1, tf)
        hit = builder.fcmp_ordered("<=", tn, tf)
        bits = builder.and_(builder.zext(builder.bitcast(hit, ir.IntType(WIDTH)), i64), args[7])
        lane_bits = ir.Constant(ir.VectorType(i64, WIDTH), [1 << k for k in range(WIDTH)])
        kept = builder.icmp_unsigned("!=", builder.and_(splat_int(builder, bits), lane_bits),
                                     ir.Constant(ir.VectorType(i64, WIDTH), [0] * WIDTH))
        near = builder.select(kept, tn, ir.Constant(d8, [math.inf] * WIDTH))
        fmin = cgutils.get_or_insert_function(builder.module, ir.FunctionType(dbl, [d8]),
                                              "llvm.vector.reduce.fmin.v8f64")
        return context.make_tuple(builder, sig.return_type, [bits, builder.call(fmin, [near])])
    return sig, codegen


@intrinsic
def popcount(typingctx, x):
    """Number of set bits of ``x``: one ``popcnt``."""
    def codegen(context, builder, sig, args):
        i64 = ir.IntType(64)
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(i64, [i64]), "llvm.ctpop.i64")
        return builder.call(fn, [args[0]])
    return types.int64(types.int64), codegen


def splat_int(builder, x):
    """An i64 value in all eight lanes of a vector (LLVM IR)."""
    i32 = ir.IntType(32)
    v = ir.VectorType(ir.IntType(64), WIDTH)
    undef = ir.Constant(v, ir.Undefined)
    return builder.shuffle_vector(builder.insert_element(undef, x, i32(0)), undef,
                                  ir.Constant(ir.VectorType(i32, WIDTH), [0] * WIDTH))



@njit(cache=True, error_model="numpy", inline="always")
def _signs(P, mask):
    """``(sx, sy, sz, same)``: the object-space direction signs (True: ``inv >= 0``) of the first ray of
    ``mask``, and whether all its rays share them."""
    first = rows8.lowest_bit(mask)
    sx = P[IX, first] >= 0.0
    sy = P[IX + 1, first] >= 0.0
    sz = P[IX + 2, first] >= 0.0
    same = True
    m = mask
    while m != 0:
        k = rows8.lowest_bit(m)
        m &= m - 1
        same = same and (P[IX, k] >= 0.0) == sx and (P[IX + 1, k] >= 0.0) == sy \
            and (P[IX + 2, k] >= 0.0) == sz
    return sx, sy, sz, same


@njit(cache=True, error_model="numpy", inline="always")
def _set_inverse(P, k, dx, dy, dz):
    """Ray ``k``'s slab constants (:func:`tracer.accel.wide.ray_inverse`) for direction ``d``."""
    ix, iy, iz, ixe, iye, ize, _, _, _ = wide.ray_inverse(dx, dy, dz)
    P[IX, k] = ix
    P[IX + 1, k] = iy
    P[IX + 2, k] = iz
    P[IX + 3, k] = ixe
    P[IX + 4, k] = iye
    P[IX + 5, k] = ize


@njit(cache=True, error_model="numpy", inline="always")
def _farthest(P, mask):
    """The farthest best distance among the rays ``mask``: a pending entry beyond it helps none of them."""
    t = -np.inf
    m = mask
    while m != 0:
        k = rows8.lowest_bit(m)
        m &= m - 1
        t = max(t, P[TB, k])
    return t


@njit(cache=True, error_model="numpy", inline="always")
def _record(P, PI, k, t, u, v, inst, slot):
    """Ray ``k``'s new best hit: distance ``t``, barycentrics ``(u, v)``, instance and the kind's slot."""
    P[TB, k] = t
    P[BU, k] = u
    P[BV, k] = v
    PI[INST, k] = inst
    PI[SLOT, k] = slot


@njit(cache=True, error_model="numpy", inline="always")
def _leaf(P, PI, tri, first, count, ox, oy, oz, mask, inst, any_hit):
    """Test the triangles ``first .. first+count-1`` against the rays ``mask`` (object space: origin ``o``);
    returns the rays of ``mask`` still looking (with ``any_hit``: those without a hit)."""
    m = mask
    while m != 0:
        k = rows8.lowest_bit(m)
        m &= m - 1
        if PI[KZ, k] < 0:
            kx, ky, kz, sx, sy, sz = ray_setup(P[RDX, k], P[RDY, k], P[RDZ, k])
            okx, oky, okz = origin_setup(ox, oy, oz, kx, ky, kz)
            PI[KX, k] = kx
            PI[KY, k] = ky
            PI[KZ, k] = kz
            P[SX, k] = sx
            P[SY, k] = sy
            P[SZ, k] = sz
            P[OKX, k] = okx
            P[OKY, k] = oky
            P[OKZ, k] = okz
        for j in range(first, first + count):
            hit, t, u, v = intersect_triangle(tri, j, P[OKX, k], P[OKY, k], P[OKZ, k], PI[KX, k], PI[KY, k],
                                              PI[KZ, k], P[SX, k], P[SY, k], P[SZ, k], P[TB, k])
            if hit:
                _record(P, PI, k, t, u, v, inst, j)
                if any_hit:
                    mask &= ~(np.int64(1) << k)
                    break
    return mask


@njit(cache=True, error_model="numpy", inline="always")
def _child4(P, bu, q, nxo, nyo, nzo, fxo, fyo, fzo, ex, ey, ez, gx, gy, gz, ox, oy, oz, mask):
    """``(t_near, hits)`` of the quantised box whose bytes start at ``bu[q]`` (planes ``origin + step scale``,
    exact, then ``- o``: :func:`tracer.accel.wide.slab4`'s arithmetic); ``nxo`` etc. the near and far planes'
    byte offsets. An empty slot is an inverted box: no ray meets it."""
    u = np.uint64(q)
    hits, t = packet_slab(P, ex + np.float64(bu[u + np.uint64(nxo)]) * gx - ox,
                          ey + np.float64(bu[u + np.uint64(nyo)]) * gy - oy,
                          ez + np.float64(bu[u + np.uint64(nzo)]) * gz - oz,
                          ex + np.float64(bu[u + np.uint64(fxo)]) * gx - ox,
                          ey + np.float64(bu[u + np.uint64(fyo)]) * gy - oy,
                          ez + np.float64(bu[u + np.uint64(fzo)]) * gz - oz, mask)
    return t, hits


@njit(cache=True, error_model="numpy", inline="always")
def _key(bi, i, hits):
    """A stack entry: the reference at ``bi[i]`` shifted up, the rays that entered it in the low byte."""
    return (np.int64(bi[i]) << 8) | hits


@njit(cache=True, error_model="numpy", inline="always")
def walk_rows_packet(P, PI, bf, bu, bi, tri, row0, tri0, ox, oy, oz, mask, inst, any_hit, stack, tstack, solo, tsolo):
    """The rays ``mask`` of the packet through a mesh's 4-wide quantised rows (:func:`tracer.accel.rows4.pack_wide`),
    in the object space set in ``P`` (origin ``o``; directions of one sign per axis). Children are visited
    nearest first by the packet's least entry distance. Hits update ``P``/``PI``; returns the rays of ``mask``
    still looking (with ``any_hit``: those without a hit). Rays reaching a row :data:`SOLO` or fewer go on from it
    by themselves (:func:`tracer.accel.wide.traverse_from`, on the stacks ``solo, tsolo``): the packet's test of
    eight lanes would do their work at several times the cost."""
    sgx, sgy, sgz, _ = _signs(P, mask)
    nxo = 0 if sgx else 12   # byte offsets of the near planes within a row's planes (xmin's or xmax's)
    nyo = 4 if sgy else 16
    nzo = 8 if sgz else 20
    fxo = 12 - nxo
    fyo = 20 - nyo
    fzo = 28 - nzo
    base = wide.STACK_BASE
    sp = base
    ref = 0
    live = mask
    tmax = _farthest(P, live)
    rays = mask
    while True:
        if ref >= 0 and popcount(rays) <= SOLO:
            m = rays
            while m != 0:
                k = rows8.lowest_bit(m)
                m &= m - 1
                hit, t, slot, u, v = wide.traverse_from(bf, bi, tri, row0, tri0, ox, oy, oz, P[RDX, k], P[RDY, k],
                                                    P[RDZ, k], P[TB, k], any_hit, solo, tsolo, ref, wide.STACK_BASE)
                if hit:
                    _record(P, PI, k, t, u, v, inst, slot)
                    if any_hit:
                        live &= ~(np.int64(1) << k)
            if live == 0:
                break
            tmax = _farthest(P, live)
        elif ref >= 0:
            r = 16 * (row0 + ref)
            q = 4 * r + 24   # the row's first quantised byte
            ex = np.float64(bf[r])
            ey = np.float64(bf[r + 1])
            ez = np.float64(bf[r + 2])
            gx = np.float64(bf[r + 3])
            gy = np.float64(bf[r + 4])
            gz = np.float64(bf[r + 5])
            for c in range(4):   # (a loop, not four inlined copies: a third of the kernel's compile time)
                t, hits = _child4(P, bu, q + c, nxo, nyo, nzo, fxo, fyo, fzo, ex, ey, ez, gx, gy, gz, ox, oy, oz, rays)
                P[TC, c] = t
                PI[KC, c] = _key(bi, r + 12 + c, hits)
            ta, ka, t1, k1, t2, k2, t3, k3 = sort4(P[TC, 0], PI[KC, 0], P[TC, 1], PI[KC, 1], P[TC, 2], PI[KC, 2],
                                                   P[TC, 3], PI[KC, 3])
            if ta < np.inf:
                if t1 < np.inf:
                    sp = push3(stack, tstack, sp, k1, k2, k3, t1, t2, t3)
                ref = ka >> 8
                rays = ka & 255
                if ref >= 0:
                    prefetch(bf, 16 * (row0 + ref))
                continue
        else:
            x = -ref - 1
            left = _leaf(P, PI, tri, tri0 + (x >> 4), x & 15, ox, oy, oz, rays, inst, any_hit)
            live = (live & ~rays) | left
            if live == 0:
                break
            tmax = _farthest(P, live)
        key, sp = pop_nearer(stack, tstack, sp, base, tmax)
        if key == MISS:
            break
        ref = key >> 8
        rays = key & live
        rays &= 255
    return live


@njit(cache=True, error_model="numpy", inline="always")
def _enter(sa, P, PI, inst, row0, tri0, ox, oy, oz, mask, any_hit, stack, tstack, solo, tsolo):
    """The rays ``mask`` against mesh instance ``inst`` (rows from ``row0``, triangles from ``tri0``), in its
    object space: as a packet when their directions there share signs, else one by one."""
    m = sa.object_from_world
    rox = m[inst, 0, 0] * ox + m[inst, 0, 1] * oy + m[inst, 0, 2] * oz + m[inst, 0, 3]
    roy = m[inst, 1, 0] * ox + m[inst, 1, 1] * oy + m[inst, 1, 2] * oz + m[inst, 1, 3]
    roz = m[inst, 2, 0] * ox + m[inst, 2, 1] * oy + m[inst, 2, 2] * oz + m[inst, 2, 3]
    rest = mask
    while rest != 0:
        k = rows8.lowest_bit(rest)
        rest &= rest - 1
        dx = P[DX, k]
        dy = P[DY, k]
        dz = P[DZ, k]
        rdx = m[inst, 0, 0] * dx + m[inst, 0, 1] * dy + m[inst, 0, 2] * dz
        rdy = m[inst, 1, 0] * dx + m[inst, 1, 1] * dy + m[inst, 1, 2] * dz
        rdz = m[inst, 2, 0] * dx + m[inst, 2, 1] * dy + m[inst, 2, 2] * dz
        P[RDX, k] = rdx
        P[RDY, k] = rdy
        P[RDZ, k] = rdz
        _set_inverse(P, k, rdx, rdy, rdz)
        PI[KZ, k] = -1   # the triangle setup is made at the first leaf
    _, _, _, same = _signs(P, mask)
    if same:
        walk_rows_packet(P, PI, sa.bvh_f, sa.bvh_f.view(np.uint8), sa.bvh_i, sa.tri_v, row0, tri0, rox, roy, roz,
                         mask, inst, any_hit, stack, tstack, solo, tsolo)
        return
    rest = mask
    while rest != 0:
        k = rows8.lowest_bit(rest)
        rest &= rest - 1
        hit, t, slot, u, v = wide.traverse_rows(sa.bvh_f, sa.bvh_i, sa.tri_v, row0, tri0, rox, roy, roz, P[RDX, k],
                                                P[RDY, k], P[RDZ, k], P[TB, k], any_hit, stack, tstack)
        if hit:
            _record(P, PI, k, t, u, v, inst, slot)


@njit(cache=True, error_model="numpy", _nrt=False)
def packet_block(sa, o, d, t_max, any_hit, lo, hi, P, PI, stack, tstack, solo, tsolo, out_t, out_inst, out_slot, out_u,
                 out_v):
    """Rays ``lo .. hi-1`` (one origin: a camera's block); raw results as :func:`tracer.accel.traverse.walk_scene`
    gives them. In a scene of one mesh instance, :data:`WIDTH` neighbours at a time (:func:`_enter`); otherwise
    one by one: across a top level of many small instances, a packet's test of each of a row's eight boxes cost
    more than eight rays' own walks saved (the paper's scene 3: ``bench/ab.py`` x0.95 on camera rays, x1.08 as
    shadow segments)."""
    rec = sa.top_rec
    if sa.top_items.shape[0] != 1 or rec[1] != mesh.KIND:
        for i in range(lo, hi):
            out_t[i], out_inst[i], out_slot[i], out_u[i], out_v[i] = walk_scene(
                sa, o[i, 0], o[i, 1], o[i, 2], d[i, 0], d[i, 1], d[i, 2], t_max[i], any_hit, stack, tstack, True)
        return
    for p0 in range(lo, hi, WIDTH):
        n = min(WIDTH, hi - p0)
        for k in range(n):
            i = p0 + k
            P[DX, k] = d[i, 0]
            P[DY, k] = d[i, 1]
            P[DZ, k] = d[i, 2]
            P[TB, k] = t_max[i]
            P[BU, k] = 0.0
            P[BV, k] = 0.0
            PI[INST, k] = -1
            PI[SLOT, k] = -1
        _enter(sa, P, PI, rec[0], rec[2], rec[3], o[p0, 0], o[p0, 1], o[p0, 2], (np.int64(1) << n) - 1, any_hit,
               stack, tstack, solo, tsolo)
        for k in range(n):
            i = p0 + k
            out_t[i] = P[TB, k]
            out_inst[i] = PI[INST, k]
            out_slot[i] = PI[SLOT, k]
            out_u[i] = P[BU, k]
            out_v[i] = P[BV, k]


@njit(cache=True, error_model="numpy")
def new_packet():
    """``(P, PI)``: a packet's state arrays."""
    return np.empty((NPF, WIDTH)), np.empty((NPI, WIDTH), np.int64)
