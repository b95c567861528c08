"""Top level: a binned-SAH BVH over instance world boxes.

It is rebuilt whenever instances are added or removed, and after many moves; a commit that only
moves a few instances *refits* it instead (:func:`refit_top`: the moved instances' leaf boxes and
their ancestors, O(k log n)), which keeps a move commit at a fraction of a millisecond at any scene
size. The policy is in :class:`tracer.Scene` (``tlas_refit``).

An instance's world box encloses its transformed surface, as tightly as a bounded cost allows: for a
mesh of at most :data:`EXACT_MAX_TRIANGLES` triangles it is the box of its transformed vertices, for a
larger one the box of the transformed boxes of its BVH's second level (up to 16, each enclosing its
triangles), for any other kind the box of the 8 transformed corners of its object box. A rotated part
bounded by its rotated object box gets a box up to several times too large; in the paper's scene 3
(randomly rotated ribbons) the tight boxes halve the total box area, and a camera ray visits 2.3
instances instead of 5.0. Every box is padded by a relative 1e-12 so float64 rounding of the
transform can never cull a ray that the object-space test would hit.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from tracer.accel import rows8
from tracer.accel.blas import build_bvh_range, collapse
from tracer.accel.rows4 import aligned_rows, down32, pack_rows, up32
from tracer.jit import njit

#: an instance visit (transform + BLAS root) costs about this many node visits (SAH)
INSTANCE_COST = 2.0
MAX_LEAF = 1
PAD = 1e-12
#: meshes up to this size are bounded by their transformed vertices (cost per instance ~ size)
EXACT_MAX_TRIANGLES = 512


@njit(cache=True, error_model="numpy", inline="always")
def _grow_point(m, i, x, y, z, acc):
    """Widen ``acc`` (lo xyz, hi xyz) by the world-space image of an object-space point."""
    wx = m[i, 0, 0] * x + m[i, 0, 1] * y + m[i, 0, 2] * z + m[i, 0, 3]
    wy = m[i, 1, 0] * x + m[i, 1, 1] * y + m[i, 1, 2] * z + m[i, 1, 3]
    wz = m[i, 2, 0] * x + m[i, 2, 1] * y + m[i, 2, 2] * z + m[i, 2, 3]
    acc[0] = min(acc[0], wx)
    acc[1] = min(acc[1], wy)
    acc[2] = min(acc[2], wz)
    acc[3] = max(acc[3], wx)
    acc[4] = max(acc[4], wy)
    acc[5] = max(acc[5], wz)


@njit(cache=True, error_model="numpy", inline="always")
def _grow(m, i, x0, y0, z0, x1, y1, z1, acc):
    """Widen ``acc`` by the 8 world-space corners of an object-space box."""
    for c in range(8):
        _grow_point(m, i, x1 if c & 1 else x0, y1 if c & 2 else y0, z1 if c & 4 else z0, acc)


@njit(cache=True, error_model="numpy", inline="always")
def _grow_row(m, i, rows_f, rows_b, r, c, acc):
    """Widen ``acc`` by child ``c`` of wide row ``r``: its quantised box, which encloses the child's exact
    box (an empty slot, inverted on every axis, adds nothing)."""
    q = 64 * r + 24 + c
    if rows_b[q] > rows_b[q + 12] or rows_b[q + 4] > rows_b[q + 16] or rows_b[q + 8] > rows_b[q + 20]:
        return
    f = 16 * r
    _grow(m, i, rows_f[f] + rows_b[q] * np.float64(rows_f[f + 3]),
          rows_f[f + 1] + rows_b[q + 4] * np.float64(rows_f[f + 4]),
          rows_f[f + 2] + rows_b[q + 8] * np.float64(rows_f[f + 5]),
          rows_f[f] + rows_b[q + 12] * np.float64(rows_f[f + 3]),
          rows_f[f + 1] + rows_b[q + 16] * np.float64(rows_f[f + 4]),
          rows_f[f + 2] + rows_b[q + 20] * np.float64(rows_f[f + 5]), acc)


@njit(cache=True, error_model="numpy")
def world_boxes(ids, world_from_object, object_box, inst_kind, mesh_kind, inst_geom, g_row0, g_tri0, g_ntri, rows_f,
                rows_i, rows_b, tri_v, out):
    """``out[ids[q]]`` = padded world box of instance ``ids[q]`` (the module's docstring says which box).

    ``inst_kind``, ``inst_geom``: per instance; ``g_row0``, ``g_tri0``, ``g_ntri``: per geometry, its
    first wide row and triangle; ``rows_f``, ``rows_i``, ``rows_b``: three flat views of the packed wide
    rows; ``tri_v``: the packed triangles, flat. An empty object box (min > max) stays empty (the
    instance is left out of the top level).
    """
    acc = np.empty(6)
    m = world_from_object
    for q in range(ids.shape[0]):
        i = ids[q]
        if object_box[i, 0] > object_box[i, 3]:
            for a in range(3):
                out[i, a] = np.inf
                out[i, 3 + a] = -np.inf
            continue
        for a in range(3):
            acc[a] = np.inf
            acc[3 + a] = -np.inf
        g = inst_geom[i]
        if inst_kind[i] != mesh_kind or g_ntri[g] == 0:
            _grow(m, i, object_box[i, 0], object_box[i, 1], object_box[i, 2], object_box[i, 3], object_box[i, 4],
                  object_box[i, 5], acc)
        elif g_ntri[g] <= EXACT_MAX_TRIANGLES:
            for j in range(3 * g_tri0[g], 3 * (g_tri0[g] + g_ntri[g])):
                _grow_point(m, i, np.float64(tri_v[3 * j]), np.float64(tri_v[3 * j + 1]), np.float64(tri_v[3 * j + 2]),
                            acc)
        else:
            r = g_row0[g]
            for c in range(4):
                ref = rows_i[16 * r + 12 + c]
                if ref >= 0:   # an interior child: its own four boxes (tighter)
                    for c2 in range(4):
                        _grow_row(m, i, rows_f, rows_b, r + ref, c2, acc)
                else:
                    _grow_row(m, i, rows_f, rows_b, r, c, acc)
        mag = max(abs(acc[0]), abs(acc[1]), abs(acc[2]), abs(acc[3]), abs(acc[4]), abs(acc[5]))
        pad = PAD * mag + 1e-300
        for a in range(3):
            out[i, a] = acc[a] - pad
            out[i, 3 + a] = acc[3 + a] + pad


@njit(cache=True, error_model="numpy")
def instance_records(items, inst_kind, inst_geom, g_row0, g_tri0, g_ntri, mesh_kind):
    """``(4 n,)`` int64: for each top-level item ``q`` (leaf order), ``[inst, kind, row0, tri0]``: its
    instance id, kind and, for a mesh, its bottom level's first row and triangle. Kind -1 marks a mesh
    without triangles, which has no rows to enter (an empty mesh has an empty box and is left out of
    the top level today; the mark keeps a walk safe should that change).

    Entering an instance through the ids took a chain of four dependent loads (item, instance,
    geometry, row), each a likely cache miss for an incoherent ray; the record, next to its
    neighbours in the leaf, is one load, and the row and the transform follow it together."""
    out = np.zeros(4 * items.shape[0], np.int64)
    for q in range(items.shape[0]):
        i = items[q]
        k = inst_kind[i]
        out[4 * q] = i
        out[4 * q + 1] = k
        if k == mesh_kind:
            g = inst_geom[i]
            if g_ntri[g] == 0:
                out[4 * q + 1] = -1
            out[4 * q + 2] = g_row0[g]
            out[4 * q + 3] = g_tri0[g]
    return out


@njit(cache=True, error_model="numpy")
def _build_top(ids, boxes):
    n = ids.shape[0]
    bmin = np.empty((n, 3))
    bmax = np.empty((n, 3))
    for q in range(n):
        for a in range(3):
            bmin[q, a] = boxes[ids[q], a]
            bmax[q, a] = boxes[ids[q], 3 + a]
    order = np.arange(n)
    cap = max(2 * n - 1, 0)
    node_box = np.empty((cap, 6))
    node_a = np.zeros(cap, np.int32)
    node_n = np.zeros(cap, np.int32)
    k = build_bvh_range(bmin, bmax, order, 0, n, node_box, node_a, node_n, 0, MAX_LEAF, INSTANCE_COST)
    items = np.empty(n, np.int32)
    for q in range(n):
        items[q] = ids[order[q]]
    node_off = np.zeros(1, np.int64)
    node_cnt = np.full(1, k, np.int64)
    boxes2, refs, _ = collapse(node_box[:k], node_a[:k], node_n[:k], node_off, node_cnt)
    # links for refits: row -> (parent row, slot in it); instance -> (row, slot) of its leaf
    r_n = refs.shape[0]
    row_parent = np.full(r_n, -1, np.int64)
    row_pslot = np.zeros(r_n, np.int64)
    item_row = np.full(boxes.shape[0], -1, np.int64)
    item_slot = np.zeros(boxes.shape[0], np.int64)
    for r in range(r_n):
        for slot in range(2):
            ref = refs[r, slot]
            if ref >= 0:
                row_parent[ref] = r
                row_pslot[ref] = slot
            else:
                x = -ref - 1
                for q in range(x >> 4, (x >> 4) + (x & 15)):
                    item_row[items[q]] = r
                    item_slot[items[q]] = slot
    return boxes2, refs, items, row_parent, row_pslot, item_row, item_slot


@njit(cache=True, error_model="numpy")
def _refit_binary(rows_f, rows_i, items, links, ids, boxes, touched):
    """Refit the binary rows in place after instances ``ids`` moved (their ``boxes`` are current).

    ``rows_f``/``rows_i``: the (R, 16) rows and their int32 view; ``links``: the last four arrays
    of :func:`_build_top`. Each moved instance's leaf box is recomputed from its items, then every
    ancestor's box, up to the root. Boxes are rounded outward to float32, as when built. Rows
    written are marked in ``touched``.
    """
    row_parent, row_pslot, item_row, item_slot = links
    for q in range(ids.shape[0]):
        i = ids[q]
        r = item_row[i]
        if r < 0:
            continue
        slot = item_slot[i]
        x = -rows_i[r, 12 + slot] - 1
        lo0 = lo1 = lo2 = np.inf
        hi0 = hi1 = hi2 = -np.inf
        for k in range(x >> 4, (x >> 4) + (x & 15)):
            it = items[k]
            lo0 = min(lo0, boxes[it, 0])
            lo1 = min(lo1, boxes[it, 1])
            lo2 = min(lo2, boxes[it, 2])
            hi0 = max(hi0, boxes[it, 3])
            hi1 = max(hi1, boxes[it, 4])
            hi2 = max(hi2, boxes[it, 5])
        while True:
            c = 6 * slot
            touched[r] = True
            rows_f[r, c] = down32(lo0)
            rows_f[r, c + 1] = down32(lo1)
            rows_f[r, c + 2] = down32(lo2)
            rows_f[r, c + 3] = up32(hi0)
            rows_f[r, c + 4] = up32(hi1)
            rows_f[r, c + 5] = up32(hi2)
            p = row_parent[r]
            if p < 0:
                break
            lo0 = min(rows_f[r, 0], rows_f[r, 6])
            lo1 = min(rows_f[r, 1], rows_f[r, 7])
            lo2 = min(rows_f[r, 2], rows_f[r, 8])
            hi0 = max(rows_f[r, 3], rows_f[r, 9])
            hi1 = max(rows_f[r, 4], rows_f[r, 10])
            hi2 = max(rows_f[r, 5], rows_f[r, 11])
            slot = row_pslot[r]
            r = p


class TopLevel(NamedTuple):
    """A top level: binary child-box rows (refitted on moves), the 8-wide rows traversal reads (``None``
    for a level traversed in binary form), leaf items and what refits need."""

    binary: np.ndarray   # (R, 16) float32, int32 view for the refs
    items: np.ndarray    # (n,) int32 instance ids, in leaf order
    links: tuple         # binary row parents and leaf positions, for refits
    rows8: np.ndarray | None   # (W, 64) float32, :func:`tracer.accel.rows8.pack8`
    src8: np.ndarray | None   # 8-wide slot -> binary (row, slot)
    rows8_of: np.ndarray | None   # binary row -> the 8-wide row its boxes sit in


def build_top(ids: np.ndarray, boxes: np.ndarray, wide: bool = True) -> TopLevel:
    """Build the top level over instances ``ids`` with world boxes ``boxes[ids]`` (8-wide rows too
    when ``wide``; no rows when there are no instances)."""
    b, refs, items, *links = _build_top(np.ascontiguousarray(ids, np.int64), boxes)
    rows = pack_rows(b, refs)
    if not wide:
        return TopLevel(rows, items, tuple(links), None, None, None)
    r8, src8 = rows8.pack8(rows)
    rows8_of = np.zeros(len(b), np.int64)   # (both slots of a binary row go to one 8-wide row)
    w, c = np.nonzero(src8 >= 0)
    rows8_of[src8[w, c] >> 1] = w
    return TopLevel(rows, items, tuple(links), r8, src8, rows8_of)


def refit_top(level: TopLevel, ids: np.ndarray, boxes: np.ndarray) -> TopLevel:
    """The top level refitted after instances ``ids`` moved (their ``boxes`` are current): the moved
    leaves and their ancestors in the binary rows, then the wide rows holding any of them. New
    arrays are returned; the published ones are never written (a running query keeps its own)."""
    rows = level.binary.copy()
    touched = np.zeros(len(rows), np.bool_)
    _refit_binary(rows, rows.view(np.int32), level.items, level.links, ids, boxes, touched)
    if level.rows8 is None or level.rows8_of is None:
        return level._replace(binary=rows)
    r8 = aligned_rows(4 * len(level.rows8)).reshape(-1, rows8.ROW)
    r8[:] = level.rows8
    rows8.refit8(r8, level.src8, rows, np.unique(level.rows8_of[touched]))
    return level._replace(binary=rows, rows8=r8)
