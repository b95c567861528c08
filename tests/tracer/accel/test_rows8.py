"""The solid top level's 8-wide float32 rows (tracer.accel.rows8): each slot holds
the binary row's box it came from, before and after a refit; every instance is reached exactly once; and
the float32 slab test never misses a box the segment meets in exact arithmetic, nor reports an entry
beyond the exact one (a pending row is culled by comparing that entry with the best hit)."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from numba import njit

from tracer.accel import tlas
from tracer.accel.rows8 import NEAR32, ROW, WIDTH, ray8, slab8
from tracer.accel.traverse import TOP8_DIST, new_stacks


def _boxes(rng: np.random.Generator, n: int, offset: float, size: float) -> np.ndarray:
    lo = offset + rng.uniform(0, size, (n, 3))
    return np.concatenate([lo, lo + rng.uniform(0.001, 0.05, (n, 3)) * size], axis=1)


def _planes(rows8: np.ndarray) -> np.ndarray:
    """(W, 6, 8) float64 planes of the rows."""
    return rows8[:, :6 * WIDTH].astype(np.float64).reshape(-1, 6, WIDTH)


def _slot_boxes_of_items(level: tlas.TopLevel) -> dict[int, list[np.ndarray]]:
    """Item -> the boxes of the slots on the way to its leaf (walking the 8-wide rows from the root)."""
    refs = level.rows8.view(np.int32)[:, 6 * WIDTH:7 * WIDTH]
    planes = _planes(level.rows8)
    out: dict[int, list[np.ndarray]] = {}
    todo = [(0, [])]
    while todo:
        w, path = todo.pop()
        for c in range(WIDTH):
            box = planes[w, :, c]
            ref = int(refs[w, c])
            if ref >= 0:
                todo.append((ref, path + [box]))
            elif ref < -1:
                x = -ref - 1
                for q in range(x >> 4, (x >> 4) + (x & 15)):
                    assert int(level.items[q]) not in out   # reached once
                    out[int(level.items[q])] = path + [box]
    return out


def test_rows8_hold_the_binary_boxes_and_reach_every_instance_once() -> None:
    rng = np.random.default_rng(2)
    n = 3000
    boxes = _boxes(rng, n, 0.0, 30.0)
    level = tlas.build_top(np.arange(n), boxes)
    assert level.rows8.ctypes.data % 64 == 0 and level.rows8.shape[1] == ROW
    assert len(level.rows8) < len(level.binary) / 3   # far fewer rows than the binary tree
    w, c = np.nonzero(level.src8 >= 0)
    src = level.src8[w, c]
    planes = _planes(level.rows8)
    for a in range(6):
        np.testing.assert_array_equal(planes[w, a, c], level.binary[src >> 1, 6 * (src & 1) + a])
    empty = level.src8 < 0
    assert np.all(planes[:, 0, :][empty] > planes[:, 3, :][empty])   # an empty slot is inverted
    paths = _slot_boxes_of_items(level)
    assert sorted(paths) == list(range(n))
    for i, path in paths.items():   # each box on the way encloses the instance's box
        for box in path:
            assert np.all(box[:3] <= boxes[i, :3]) and np.all(box[3:] >= boxes[i, 3:])


def test_refit_reaches_the_rows8() -> None:
    """A move refits the top level; the 8-wide rows then hold the refitted binary boxes, and every moved
    instance's new box lies in each slot box on the way to it. The rows published before are kept."""
    rng = np.random.default_rng(3)
    n = 800
    boxes = _boxes(rng, n, -10.0, 20.0)
    level = tlas.build_top(np.arange(n), boxes)
    before = level.rows8.copy()
    moved = rng.choice(n, 25, replace=False)
    boxes[moved] += 5.0
    refitted = tlas.refit_top(level, moved.astype(np.int64), boxes)
    np.testing.assert_array_equal(level.rows8, before)
    assert not np.array_equal(refitted.rows8, before)
    assert refitted.rows8.ctypes.data % 64 == 0
    w, c = np.nonzero(refitted.src8 >= 0)
    src = refitted.src8[w, c]
    planes = _planes(refitted.rows8)
    for a in range(6):
        np.testing.assert_array_equal(planes[w, a, c], refitted.binary[src >> 1, 6 * (src & 1) + a])
    paths = _slot_boxes_of_items(refitted)
    for i in moved:
        for box in paths[int(i)]:
            assert np.all(box[:3] <= boxes[i, :3]) and np.all(box[3:] >= boxes[i, 3:])


@njit(error_model="numpy")
def _slab8_all(rows_f, o, d, t_max, pairs):
    """slab8 of row ``pairs[k, 1]`` for ray ``pairs[k, 0]``: the hit mask and the eight entry distances."""
    stack, tstack = new_stacks()
    mask = np.empty(len(pairs), np.int64)
    dist = np.empty((len(pairs), WIDTH))
    for k in range(len(pairs)):
        i = pairs[k, 0]
        onx, ony, onz, ofx, ofy, ofz, ix, iy, iz, ixe, iye, ize, xl, yl, zl = ray8(o[i, 0], o[i, 1], o[i, 2],
                                                                                    d[i, 0], d[i, 1], d[i, 2])
        t32 = np.float64(np.float32(t_max[i]))
        if t32 < t_max[i]:
            t32 = np.float64(np.nextafter(np.float32(t32), np.float32(np.inf)))
        mask[k] = slab8(rows_f, ROW * pairs[k, 1], onx, ony, onz, ofx, ofy, ofz, ix, iy, iz, ixe, iye, ize, xl, yl,
                        zl, t32, tstack, TOP8_DIST)
        dist[k] = tstack[TOP8_DIST:TOP8_DIST + WIDTH]
    return mask, dist


def _exact(lo, hi, o, d, t_max):
    """Entry distance of the segment ``o + t d``, ``0 <= t <= t_max``, into the closed box, in exact
    arithmetic; None when it misses."""
    tn, tf = Fraction(0), Fraction(t_max) if np.isfinite(t_max) else None
    for a in range(3):
        if d[a] == 0:
            if not lo[a] <= o[a] <= hi[a]:
                return None
            continue
        t0 = (Fraction(lo[a]) - Fraction(o[a])) / Fraction(d[a])
        t1 = (Fraction(hi[a]) - Fraction(o[a])) / Fraction(d[a])
        t0, t1 = min(t0, t1), max(t0, t1)
        tn = max(tn, t0)
        tf = t1 if tf is None else min(tf, t1)
    return tn if tf is None or tn <= tf else None


@pytest.mark.parametrize("offset, size", [(0.0, 1.0), (1e5, 1e-2), (-3e4, 50.0), (1e-3, 1e-6)])
def test_float32_slab_test_never_misses_a_box_the_segment_meets(offset, size) -> None:
    """Against exact rational arithmetic, on random segments and on segments aimed at box corners and
    edges (grazing, hit or missed by an ulp), some parallel to an axis, some starting on a box's face:
    every box met is reported, at a distance no farther than the exact entry."""
    rng = np.random.default_rng(11)
    level = tlas.build_top(np.arange(2000), _boxes(rng, 2000, offset, size))
    planes = _planes(level.rows8)
    full = np.argwhere(level.src8 >= 0)   # (row, slot) holding a box
    k = 1500
    pick = full[rng.integers(len(full), size=k)]
    box = planes[pick[:, 0], :, pick[:, 1]]   # (k, 6)
    o = offset + rng.uniform(-0.5, 1.5, (k, 3)) * size
    target = box[:, :3] + (box[:, 3:] - box[:, :3]) * rng.integers(0, 2, (k, 3))   # a corner
    edge = rng.random(k) < 0.3
    target[edge, 0] = (box[edge, 0] + box[edge, 3]) / 2   # or the middle of an edge
    d = target - o
    d[rng.random(k) < 0.3] = rng.normal(size=3)   # or anywhere
    d[:100, 1] = 0.0   # parallel to a slab
    on_face = slice(100, 200)
    o[on_face, 2] = box[on_face, 2]   # starting on a face's plane
    t_max = np.where(rng.random(k) < 0.5, np.inf, rng.uniform(0.5, 2.0, k))
    pairs = np.stack([np.arange(k), pick[:, 0]], axis=1)
    mask, dist = _slab8_all(level.rows8.reshape(-1), o, d, t_max, pairs)
    met = 0
    for q in range(k):
        t = _exact(box[q, :3], box[q, 3:], o[q], d[q], t_max[q])
        if t is None:
            continue
        met += 1
        slot = pick[q, 1]
        assert mask[q] >> slot & 1, (q, box[q], o[q], d[q], t_max[q])
        assert Fraction(dist[q, slot]) <= t
    assert met > k / 4   # the grazing segments do meet their boxes often


def test_float32_slab_test_is_tight_near_the_origin() -> None:
    """Conservative, not loose: near the origin it reports the boxes a float64 slab test reports, but for
    rays that pass within float32 rounding of a box, at entry distances short of the exact ones by no more
    than :data:`NEAR32` and float32 rounding."""
    rng = np.random.default_rng(5)
    level = tlas.build_top(np.arange(3000), _boxes(rng, 3000, 0.0, 1.0))
    k = 2000
    o = rng.uniform(-0.5, 1.5, (k, 3))
    d = rng.normal(size=(k, 3))
    pairs = np.stack([np.repeat(np.arange(k), 4), rng.integers(10, size=4 * k)], axis=1)   # rows near the root
    mask, dist = _slab8_all(level.rows8.reshape(-1), o, d, np.full(k, np.inf), pairs)
    planes = _planes(level.rows8)[pairs[:, 1]]
    oo, dd = o[pairs[:, 0], :, None], d[pairs[:, 0], :, None]
    t0, t1 = (planes[:, :3] - oo) / dd, (planes[:, 3:] - oo) / dd
    near = np.maximum(np.minimum(t0, t1).max(axis=1), 0.0)
    far = np.maximum(t0, t1).min(axis=1)
    hit64 = (near <= far) & np.all(planes[:, :3] <= planes[:, 3:], axis=1)   # (empty slots are inverted boxes)
    hit32 = (mask[:, None] >> np.arange(WIDTH)) & 1 == 1
    assert np.all(hit32[hit64])
    assert hit64.sum() > 500 and (hit32 & ~hit64).sum() <= 0.01 * hit64.sum()
    # short by at most NEAR32, float32 rounding of the distance and of the origin (tracer.accel.rows4.down32 and
    # up32 round outward by up to 3 ulps: 4 ulps of |o|, over |d|)
    oi, di = o[pairs[:, 0]], d[pairs[:, 0]]
    slack = near * (1 - NEAR32 + 4 * 2.0**-24) + (np.abs(oi).max(axis=1) * 2.0**-21 / np.abs(di).min(axis=1))[:, None]
    assert np.all(dist[hit64] >= near[hit64] - slack[hit64])


def test_origin_beyond_float32_range() -> None:
    """An origin farther out than float32 reaches (|o| > 3.4e38) still finds the box it points at."""
    boxes = np.array([[0.0, 0.0, 0.0, 1.0, 1.0, 1.0], [5.0, 5.0, 5.0, 6.0, 6.0, 6.0], [9.0, 0.0, 0.0, 9.5, 1.0, 1.0]])
    level = tlas.build_top(np.arange(3), boxes)
    o = np.array([[1e39, 0.5, 0.5], [-1e39, 0.5, 0.5], [0.5, 0.5, 1e300]])
    d = np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    pairs = np.array([[i, 0] for i in range(3)])
    mask, dist = _slab8_all(level.rows8.reshape(-1), o, d, np.full(3, np.inf), pairs)
    planes = _planes(level.rows8)
    unit = [s for s in range(WIDTH) if level.src8[0, s] >= 0 and np.array_equal(planes[0, :, s], boxes[0])]
    assert len(unit) == 1   # the root row holds the three boxes
    for q in range(3):
        assert mask[q] >> unit[0] & 1, q
        assert 0.0 < dist[q, unit[0]] <= abs(o[q]).max()
