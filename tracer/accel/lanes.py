"""Batched closest-hit and any-hit queries with several rays in flight on each core.

One ray's traversal is a chain of dependent loads: the next row's address is known only once the
current row is tested and sorted, and an incoherent ray misses the cache on almost every row. Here a
core keeps :data:`LANES` rays in flight and advances them in turn by one step each (one row, one
leaf, or asking for an instance then entering it): while one ray waits for its row, the others
compute, and the row or transform asked for by a step (``prefetch``) has the other lanes' steps to
arrive in. The answers are those of
:func:`tracer.accel.traverse.closest_with_stacks` / :func:`tracer.accel.traverse.any_with_stacks` ray by ray.

Each lane's state lives in two small arrays (``F`` floats, ``I`` integers; field indices below),
its stacks in its own part of the flat stack arrays (top level, then bottom level, as in
:func:`tracer.accel.traverse.new_stacks`). Meshes are walked step by step here; any other solid kind is
intersected in one go through :mod:`tracer.kinds.dispatch`, so a new kind needs no change here.

A block of rays that start at one point and point nearly the same way, neighbour after neighbour (a
camera's), skips the lanes: such rays walk the same rows in the same order, find them in the cache, and
would only pay for the lanes' bookkeeping (measured: 10-15 % slower for camera rays); they walk in packets
of eight instead (:mod:`tracer.accel.packets`; one by one across a top level of many instances). Rays
from one point in scattered directions (a point source's) are as incoherent as any
and take the lanes.
"""

from __future__ import annotations

import math

import numpy as np

from tracer.accel import packets, rows8
from tracer.accel.rows4 import up32
from tracer.accel.traverse import STACK_LEN, TOP8_BASE, TOP8_DIST, new_stacks, public_hit, to_object
from tracer.accel.triangle import intersect_triangle, origin_setup, ray_setup
from tracer.accel.wide import MISS, STACK_BASE, pop_nearer, prefetch, prefetch_ref, push3, ray_inverse, slab4_sorted
from tracer.jit import njit, prange
from tracer.kinds import dispatch, mesh

#: rays in flight per core. Eight, not four (issue 39): an incoherent ray misses the cache on most rows, and four
#: other lanes' steps were too few to cover the wait (``bench/ab.py``, one thread, 200,000 incoherent rays, 4 -> 8:
#: wall time x0.78 on the 1M-triangle mesh, x0.85 on scene 3 with two levels, x0.84 on it flattened; answers alike)
LANES = 8
#: rays per parallel block
BLOCK = 256
#: a block is coherent when the mean squared distance between neighbours' unit directions is below
#: this (about 6 degrees between neighbours; a camera's neighbouring pixels are a fraction of a
#: degree apart, random directions 2 on average)
COHERENT = 0.01
_SPAN = STACK_LEN   # one lane's part of the stack arrays, laid out as new_stacks()'s

# F: float fields
OX, OY, OZ, DX, DY, DZ = 0, 1, 2, 3, 4, 5               # world ray
W8 = 6                                                  # its tracer.accel.rows8.ray8 constants: 6..17 (_start)
BEST_T, BU, BV = 18, 19, 20
T32 = 21                                                # BEST_T rounded up to float32 (_set_best)
CO = 22                                                 # object-space origin 22..24, direction 25..27
CIX = 28                                                # object-space ix .. ize: 28..33 (_set_ray)
SX = 34                                                 # triangle shear sx, sy, sz: 34..36
NF = 37
# I: integer fields
RAY, STATE, TREF, TSP, Q, QEND, BREF, BSP = 0, 1, 2, 3, 4, 5, 6, 7
WXL = 8                                                 # world near planes 8..10
CXL = 11                                                # object near planes 11..13
KX = 14                                                 # triangle axes 14..16 (KZ < 0: not made yet)
ROW0, TRI0, INST, BEST_INST, BEST_SLOT = 17, 18, 19, 20, 21
NI = 22
# STATE values
TOP, ITEMS, ENTER, BOTTOM, DONE = 0, 1, 2, 3, 4


@njit(cache=True, error_model="numpy", inline="always")
def _set_ray(F, I, L, f, i, ox, oy, oz, dx, dy, dz):
    """Store a ray in lane ``L``: origin and direction at ``F[L, f : f+6]``, its slab constants
    (:func:`tracer.accel.wide.ray_inverse`) at ``F[L, f+6 : f+12]`` and ``I[L, i : i+3]``."""
    F[L, f] = ox
    F[L, f + 1] = oy
    F[L, f + 2] = oz
    F[L, f + 3] = dx
    F[L, f + 4] = dy
    F[L, f + 5] = dz
    ix, iy, iz, ixe, iye, ize, xl, yl, zl = ray_inverse(dx, dy, dz)
    F[L, f + 6] = ix
    F[L, f + 7] = iy
    F[L, f + 8] = iz
    F[L, f + 9] = ixe
    F[L, f + 10] = iye
    F[L, f + 11] = ize
    I[L, i] = xl
    I[L, i + 1] = yl
    I[L, i + 2] = zl


@njit(cache=True, error_model="numpy", inline="always")
def _start(F, I, L, ray, o, d, t_max, single):
    """Load ray ``ray`` into lane ``L``: at the top level's root, or with ``single`` (a top level of one
    instance) at that instance, whose bottom level's first row tests what its box would."""
    ox, oy, oz, dx, dy, dz = o[ray, 0], o[ray, 1], o[ray, 2], d[ray, 0], d[ray, 1], d[ray, 2]
    F[L, OX] = ox
    F[L, OY] = oy
    F[L, OZ] = oz
    F[L, DX] = dx
    F[L, DY] = dy
    F[L, DZ] = dz
    _set_best(F, L, t_max[ray])
    F[L, BU] = 0.0
    F[L, BV] = 0.0
    I[L, RAY] = ray
    I[L, TSP] = L * _SPAN + TOP8_BASE
    I[L, BEST_INST] = -1
    I[L, BEST_SLOT] = -1
    if single:
        I[L, Q] = 0
        I[L, QEND] = 1
        I[L, STATE] = ITEMS
        return
    I[L, STATE] = TOP
    I[L, TREF] = 0
    onx, ony, onz, ofx, ofy, ofz, ix, iy, iz, ixe, iye, ize, xl, yl, zl = rows8.ray8(ox, oy, oz, dx, dy, dz)
    F[L, W8] = onx
    F[L, W8 + 1] = ony
    F[L, W8 + 2] = onz
    F[L, W8 + 3] = ofx
    F[L, W8 + 4] = ofy
    F[L, W8 + 5] = ofz
    F[L, W8 + 6] = ix
    F[L, W8 + 7] = iy
    F[L, W8 + 8] = iz
    F[L, W8 + 9] = ixe
    F[L, W8 + 10] = iye
    F[L, W8 + 11] = ize
    I[L, WXL] = xl
    I[L, WXL + 1] = yl
    I[L, WXL + 2] = zl


@njit(cache=True, error_model="numpy", inline="always")
def _set_best(F, L, t):
    F[L, BEST_T] = t
    F[L, T32] = np.float64(up32(t))


@njit(cache=True, error_model="numpy", inline="always")
def _pop_top(I, F, L, stack, tstack):
    """Next pending top-level entry, or DONE."""
    ref, sp = pop_nearer(stack, tstack, I[L, TSP], L * _SPAN + TOP8_BASE, F[L, BEST_T])
    I[L, TSP] = sp
    if ref == MISS:
        I[L, STATE] = DONE
    else:
        I[L, TREF] = ref
        I[L, STATE] = TOP


@njit(cache=True, error_model="numpy", inline="always")
def _step_top(sa, F, I, L, stack, tstack):
    """Visit one top-level row (8-wide, :mod:`tracer.accel.rows8`); a leaf reached becomes the lane's item range."""
    ref = I[L, TREF]
    if ref < 0:
        x = -ref - 1
        I[L, Q] = x >> 4
        I[L, QEND] = (x >> 4) + (x & 15)
        I[L, STATE] = ITEMS
        return
    bf = sa.top_f
    r = rows8.ROW * ref
    dist = L * _SPAN + TOP8_DIST
    hits = rows8.slab8(bf, r, F[L, W8], F[L, W8 + 1], F[L, W8 + 2], F[L, W8 + 3], F[L, W8 + 4], F[L, W8 + 5],
                       F[L, W8 + 6], F[L, W8 + 7], F[L, W8 + 8], F[L, W8 + 9], F[L, W8 + 10], F[L, W8 + 11],
                       I[L, WXL], I[L, WXL + 1], I[L, WXL + 2], F[L, T32], tstack, dist)
    if hits != 0:
        ref, I[L, TSP] = rows8.descend8(sa.top_i, r, hits, stack, tstack, dist, I[L, TSP])
        I[L, TREF] = ref
        if ref >= 0:
            for line in range(0, rows8.ROW, 16):
                prefetch(bf, rows8.ROW * ref + line)
        else:   # a leaf: its first instance's record (tracer.accel.tlas.instance_records)
            prefetch(sa.top_rec, 4 * ((-ref - 1) >> 4))
        return
    _pop_top(I, F, L, stack, tstack)


@njit(cache=True, error_model="numpy", inline="always")
def _step_items(sa, F, I, L, stack, tstack):
    """Ask for the next instance of the current top-level leaf: its transform and, for a mesh, its
    bottom level's first row, to be entered at the lane's next turn (:func:`_step_enter`), when they
    have had the other lanes' steps to arrive; when the leaf is exhausted, go back to the top level's
    stack."""
    q = I[L, Q]
    end = I[L, QEND]
    rec = sa.top_rec
    while q < end:
        kind = rec[4 * q + 1]
        if kind >= 0:
            prefetch(sa.object_from_world, 12 * rec[4 * q])        # its 96 bytes span two lines
            prefetch(sa.object_from_world, 12 * rec[4 * q] + 11)
            if kind == mesh.KIND:
                prefetch(sa.bvh_f, 16 * rec[4 * q + 2])
            I[L, Q] = q
            I[L, STATE] = ENTER
            return
        q += 1
    I[L, Q] = q
    _pop_top(I, F, L, stack, tstack)


@njit(cache=True, error_model="numpy", inline="always")
def _step_enter(sa, F, I, L, any_hit, scratch, tscratch):
    """Enter instance ``Q`` of the current leaf (asked for by :func:`_step_items`): a mesh's bottom
    level is walked step by step from the next turn on, any other kind intersected at once."""
    q = I[L, Q]
    rec = sa.top_rec
    inst = rec[4 * q]
    I[L, Q] = q + 1
    I[L, STATE] = ITEMS
    rox, roy, roz, rdx, rdy, rdz = to_object(sa.object_from_world, inst, F[L, OX], F[L, OY], F[L, OZ], F[L, DX],
                                              F[L, DY], F[L, DZ])
    if rec[4 * q + 1] == mesh.KIND:
        _set_ray(F, I, L, CO, CXL, rox, roy, roz, rdx, rdy, rdz)
        I[L, KX + 2] = -1
        I[L, ROW0] = rec[4 * q + 2]
        I[L, TRI0] = rec[4 * q + 3]
        I[L, INST] = inst
        I[L, BREF] = 0
        I[L, BSP] = L * _SPAN + STACK_BASE
        I[L, STATE] = BOTTOM
        return
    hit, t, slot, u, v = dispatch.intersect_solid(sa, inst, rox, roy, roz, rdx, rdy, rdz, F[L, BEST_T], any_hit,
                                                  scratch, tscratch)
    if hit:
        _set_best(F, L, t)
        F[L, BU] = u
        F[L, BV] = v
        I[L, BEST_INST] = inst
        I[L, BEST_SLOT] = slot
        if any_hit:
            I[L, STATE] = DONE


@njit(cache=True, error_model="numpy", inline="always")
def _step_bottom(sa, F, I, L, stack, tstack, any_hit):
    """Visit one row or one leaf of the current instance's bottom level (as
    :func:`tracer.accel.wide.traverse_rows`); when its stack is empty, resume the leaf's items."""
    ref = I[L, BREF]
    row0 = I[L, ROW0]
    tri0 = I[L, TRI0]
    bf = sa.bvh_f
    bi = sa.bvh_i
    tri = sa.tri_v
    if ref >= 0:
        r = 16 * (row0 + ref)
        n, t1, t2, t3, c0, c1, c2, c3 = slab4_sorted(bf, r, F[L, CO], F[L, CO + 1], F[L, CO + 2], F[L, CIX],
                                                     F[L, CIX + 1], F[L, CIX + 2], F[L, CIX + 3], F[L, CIX + 4],
                                                     F[L, CIX + 5], I[L, CXL], I[L, CXL + 1], I[L, CXL + 2],
                                                     F[L, BEST_T])
        if n > 0:
            ref = np.int64(bi[r + 12 + c0])
            I[L, BREF] = ref
            prefetch_ref(bf, tri, row0, tri0, ref)
            # pushed without testing n > 1: with the lanes' branches interleaved, that test was
            # mispredicted often enough to cost more than the three stores it saves
            I[L, BSP] = push3(stack, tstack, I[L, BSP], bi[r + 12 + c1], bi[r + 12 + c2], bi[r + 12 + c3],
                              t1, t2, t3)
            return
    else:
        if I[L, KX + 2] < 0:
            kx, ky, kz, sx, sy, sz = ray_setup(F[L, CO + 3], F[L, CO + 4], F[L, CO + 5])
            I[L, KX] = kx
            I[L, KX + 1] = ky
            I[L, KX + 2] = kz
            F[L, SX] = sx
            F[L, SX + 1] = sy
            F[L, SX + 2] = sz
        kx = I[L, KX]
        ky = I[L, KX + 1]
        kz = I[L, KX + 2]
        sx = F[L, SX]
        sy = F[L, SX + 1]
        sz = F[L, SX + 2]
        ox = F[L, CO]
        oy = F[L, CO + 1]
        oz = F[L, CO + 2]
        okx, oky, okz = origin_setup(ox, oy, oz, kx, ky, kz)
        x = -ref - 1
        first = tri0 + (x >> 4)
        for j in range(first, first + (x & 15)):
            hit, t, u, v = intersect_triangle(tri, j, okx, oky, okz, kx, ky, kz, sx, sy, sz, F[L, BEST_T])
            if hit:
                _set_best(F, L, t)
                F[L, BU] = u
                F[L, BV] = v
                I[L, BEST_INST] = I[L, INST]
                I[L, BEST_SLOT] = j
                if any_hit:
                    I[L, STATE] = DONE
                    return
    ref, sp = pop_nearer(stack, tstack, I[L, BSP], L * _SPAN + STACK_BASE, F[L, BEST_T])
    I[L, BSP] = sp
    if ref == MISS:
        I[L, STATE] = ITEMS
    else:
        I[L, BREF] = ref


@njit(cache=True, error_model="numpy", _nrt=False)
def _block(sa, o, d, t_max, any_hit, lo, hi, F, I, stack, tstack, scratch, tscratch, out_t, out_inst, out_slot,
           out_u, out_v):
    """Rays ``lo .. hi-1``, :data:`LANES` at a time; raw results (``out_slot``: the kind's slot)."""
    single = sa.top_items.shape[0] == 1
    nxt = lo
    active = 0
    for L in range(LANES):
        if nxt < hi:
            _start(F, I, L, nxt, o, d, t_max, single)
            nxt += 1
            active += 1
        else:
            I[L, STATE] = DONE
            I[L, RAY] = -1
    if sa.top_f.shape[0] == 0:
        for L in range(LANES):
            I[L, STATE] = DONE
    L = 0
    while active > 0:
        st = I[L, STATE]
        if st == BOTTOM:
            _step_bottom(sa, F, I, L, stack, tstack, any_hit)
        elif st == TOP:
            _step_top(sa, F, I, L, stack, tstack)
        elif st == ITEMS:
            _step_items(sa, F, I, L, stack, tstack)
        elif st == ENTER:
            _step_enter(sa, F, I, L, any_hit, scratch, tscratch)
        elif I[L, RAY] >= 0:
            ray = I[L, RAY]
            out_t[ray] = F[L, BEST_T]
            out_inst[ray] = I[L, BEST_INST]
            out_slot[ray] = I[L, BEST_SLOT]
            out_u[ray] = F[L, BU]
            out_v[ray] = F[L, BV]
            if nxt < hi:
                _start(F, I, L, nxt, o, d, t_max, single)
                if sa.top_f.shape[0] == 0:
                    I[L, STATE] = DONE
                nxt += 1
            else:
                I[L, RAY] = -1
                active -= 1
        L += 1
        if L == LANES:
            L = 0


@njit(cache=True, error_model="numpy", inline="always")
def is_coherent(o, d, lo, hi):
    """True when rays ``lo .. hi-1`` all start at one point and neighbours point nearly the same way
    (:data:`COHERENT`)."""
    s = 0.0
    a = 1.0 / math.sqrt(d[lo, 0] ** 2 + d[lo, 1] ** 2 + d[lo, 2] ** 2)   # 1 / |d| of the previous ray
    for i in range(lo + 1, hi):
        if o[i, 0] != o[lo, 0] or o[i, 1] != o[lo, 1] or o[i, 2] != o[lo, 2]:
            return False
        b = 1.0 / math.sqrt(d[i, 0] ** 2 + d[i, 1] ** 2 + d[i, 2] ** 2)
        s += ((d[i, 0] * b - d[i - 1, 0] * a) ** 2 + (d[i, 1] * b - d[i - 1, 1] * a) ** 2
              + (d[i, 2] * b - d[i - 1, 2] * a) ** 2)
        a = b
    return s <= COHERENT * (hi - lo - 1)


@njit(cache=True, error_model="numpy", inline="always", _nrt=True)   # allocates its lanes, once per block
def _trace_block(sa, o, d, t_max, any_hit, lo, hi, out_t, out_inst, out_slot, out_u, out_v):
    """Rays ``lo .. hi-1`` in lanes, or in packets (:mod:`tracer.accel.packets`) when they are coherent."""
    F, I, stack, tstack, scratch, tscratch = _lane_state()
    if is_coherent(o, d, lo, hi):
        P, PI = packets.new_packet()
        packets.packet_block(sa, o, d, t_max, any_hit, lo, hi, P, PI, scratch, tscratch, stack, tstack, out_t, out_inst,
                             out_slot, out_u, out_v)
    else:
        _block(sa, o, d, t_max, any_hit, lo, hi, F, I, stack, tstack, scratch, tscratch, out_t, out_inst, out_slot,
               out_u, out_v)


@njit(cache=True, error_model="numpy", _nrt=False)
def _finish_closest(sa, lo, hi, out_t, out_inst, out_slot, out_u, out_v, out_n):
    """Raw results -> the public ones (:func:`tracer.accel.traverse.public_hit`)."""
    for i in range(lo, hi):
        (out_t[i], out_inst[i], out_slot[i], out_u[i], out_v[i],
         out_n[i, 0], out_n[i, 1], out_n[i, 2]) = public_hit(sa, out_t[i], out_inst[i], out_slot[i], out_u[i], out_v[i])


@njit(cache=True, error_model="numpy")
def _lane_state():
    stack = np.empty(LANES * _SPAN, np.int64)
    tstack = np.empty(LANES * _SPAN)
    scratch, tscratch = new_stacks()
    return np.empty((LANES, NF)), np.empty((LANES, NI), np.int64), stack, tstack, scratch, tscratch


@njit(parallel=True, cache=True, error_model="numpy")
def batch(sa, o, d, t_max, any_hit, out_t, out_inst, out_prim, out_u, out_v, out_n):
    """Batched :func:`tracer.accel.traverse.intersect_closest` (or, with ``any_hit``, the first hit found, as
    :func:`tracer.accel.traverse.intersect_any`: then ``out_inst >= 0`` is the answer, the rest is raw) over
    rays ``o[i], d[i]`` (k, 3), ``t_max`` (k,); parallel over blocks of rays, :data:`LANES` rays in
    flight in each (unless they are a camera's coherent rays). One kernel for both queries: each
    compiles the traversal twice (lanes and one by one), which is a cold-compile cost worth paying
    once."""
    k = o.shape[0]
    nb = (k + BLOCK - 1) // BLOCK
    for b in prange(nb):
        lo = b * BLOCK
        hi = min(k, lo + BLOCK)
        _trace_block(sa, o, d, t_max, any_hit, lo, hi, out_t, out_inst, out_prim, out_u, out_v)
        if not any_hit:   # an any-hit answer needs no primitive id nor normal
            _finish_closest(sa, lo, hi, out_t, out_inst, out_prim, out_u, out_v, out_n)
