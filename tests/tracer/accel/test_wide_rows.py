"""The 4-wide quantised rows of the bottom levels (tracer.accel.rows4.pack_wide): every stored box encloses its
child's exact box, whatever the coordinates' magnitude (the top level's 8-wide rows: test_rows8.py)."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from tracer.accel.blas import build_meshes, collapse, gather_triangles
from tracer.accel.rows4 import pack_wide, widen
from tracer.accel.wide import BOX_EPS, ray_inverse, slab4_sorted


def _dequantise(rows: np.ndarray) -> np.ndarray:
    """(W, 24) float64 planes ``origin + q scale``, as traversal computes them."""
    origin = rows[:, 0:3].astype(np.float64)
    scale = rows[:, 3:6].astype(np.float64)
    q = rows.view(np.uint8)[:, 24:48].astype(np.float64).reshape(-1, 6, 4)
    return (origin[:, [0, 1, 2, 0, 1, 2], None] + q * scale[:, [0, 1, 2, 0, 1, 2], None]).reshape(-1, 24)


def _binary_rows(tri: np.ndarray):
    m = len(tri)
    tri_off = np.array([0, m], np.int64)
    tri_v = np.empty((m, 9))
    gather_triangles(tri.reshape(-1, 3), np.arange(3 * m).reshape(m, 3), tri_off, np.array([0, 3 * m]), tri_v)
    order, node_box, node_a, node_n, node_cnt = build_meshes(tri_v, tri_off, 4, 1.0)
    return collapse(node_box, node_a, node_n, np.zeros(1, np.int64), node_cnt)


@pytest.mark.parametrize("offset, size", [(0.0, 1.0), (1e5, 1.0), (1e5, 1e-3), (-3e4, 50.0), (1e-3, 1e-6)])
def test_quantised_boxes_enclose_the_exact_ones(offset, size) -> None:
    rng = np.random.default_rng(7)
    c = offset + rng.uniform(0, size, (3000, 1, 3))
    tri = (c + rng.normal(0, size / 200, (3000, 3, 3))).astype(np.float32).astype(np.float64)
    boxes, refs, cnt = _binary_rows(tri)
    wboxes, wrefs, _ = widen(boxes, refs, cnt)
    rows, wcnt = pack_wide(boxes, refs, cnt)
    assert rows.ctypes.data % 64 == 0
    assert wcnt[0] == len(rows) < len(boxes)   # fewer rows than the binary tree
    deq = _dequantise(rows)
    full = wboxes[:, 0:4] <= wboxes[:, 12:16]   # slots holding a box
    for a in range(3):
        lo, hi = deq[:, 4 * a:4 * a + 4], deq[:, 4 * (a + 3):4 * (a + 3) + 4]
        assert np.all(lo[full] <= wboxes[:, 4 * a:4 * a + 4][full])
        assert np.all(hi[full] >= wboxes[:, 4 * (a + 3):4 * (a + 3) + 4][full])
        # and tightly: within a few grid steps of the exact box, relative to the row's extent
        step = rows[:, 3 + a].astype(np.float64)[:, None] * np.ones((1, 4))
        assert np.all((wboxes[:, 4 * a:4 * a + 4] - lo)[full] <= step[full])
        assert np.all((hi - wboxes[:, 4 * (a + 3):4 * (a + 3) + 4])[full] <= step[full])
    assert np.array_equal(rows.view(np.int32)[:, 12:16], wrefs)


@njit(error_model="numpy")
def _slab4_all(rows_f, o, d, t_max):
    out = np.empty((len(o), len(rows_f) // 16, 8))
    for i in range(len(o)):
        ix, iy, iz, ixe, iye, ize, xl, yl, zl = ray_inverse(d[i, 0], d[i, 1], d[i, 2])
        for w in range(len(rows_f) // 16):
            n, t1, t2, t3, c0, c1, c2, c3 = slab4_sorted(rows_f, 16 * w, o[i, 0], o[i, 1], o[i, 2], ix, iy, iz,
                                                  ixe, iye, ize, xl, yl, zl, t_max[i])
            out[i, w, 0], out[i, w, 1], out[i, w, 2], out[i, w, 3] = n, t1, t2, t3
            out[i, w, 4], out[i, w, 5], out[i, w, 6], out[i, w, 7] = c0, c1, c2, c3
    return out


def test_vector_slab_test_sorts_the_hits_of_a_scalar_slab_test() -> None:
    """slab4_sorted (vector slab test and sorting network) against the same test lane by lane in numpy:
    the same boxes hit, nearest first, each entry distance at most 3 ulp below the scalar one."""
    rng = np.random.default_rng(11)
    tri = rng.uniform(-1, 1, (4000, 3, 3)).astype(np.float32).astype(np.float64) * 0.05
    tri += rng.uniform(-1, 1, (4000, 1, 3))
    rows, _ = pack_wide(*_binary_rows(tri))
    k = 1000
    o = rng.uniform(-1.5, 1.5, (k, 3))
    d = rng.normal(size=(k, 3))
    d[:20, 0] = 0.0   # parallel to a slab: its NaN products must be ignored, not miss
    t_max = np.where(rng.random(k) < 0.5, np.inf, rng.uniform(0, 2, k))
    got = _slab4_all(rows.reshape(-1), o, d, t_max)
    deq = _dequantise(rows).reshape(-1, 6, 4)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / d   # d = +0: +inf, the near plane is the low one (as ray_inverse chooses)
        pos = (inv >= 0)[:, None, :, None]
        lo, hi = deq[None, :, 0:3, :], deq[None, :, 3:6, :]
        t_near = (np.where(pos, lo, hi) - o[:, None, :, None]) * inv[:, None, :, None]
        t_far = (np.where(pos, hi, lo) - o[:, None, :, None]) * (inv * BOX_EPS)[:, None, :, None]
    near = np.nanmax(np.concatenate([np.zeros_like(t_near[:, :, :1]), t_near], axis=2), axis=2)
    far = np.nanmin(t_far, axis=2)
    far = np.minimum(far, t_max[:, None, None])
    hit = near <= far
    n = got[..., 0].astype(int)
    assert np.array_equal(n, hit.sum(axis=2))
    assert np.bincount(n.ravel(), minlength=5).min() > 40   # rows with 0, 1, 2, 3 and 4 hits, all tested
    slots = got[..., 4:8].astype(int)
    for i, w in zip(*np.nonzero(n), strict=True):
        s = slots[i, w, :n[i, w]]
        assert set(s) == set(np.flatnonzero(hit[i, w]))
        t_ref = near[i, w, s]
        assert np.all(np.diff(t_ref) >= 0)
        t_got = got[i, w, 1:n[i, w]]
        assert np.all((t_ref[1:].view(np.int64) - t_got.view(np.int64)) // 4 == 0)   # 0 to 3 ulp below
        assert np.all(np.isinf(got[i, w, n[i, w]:4]))
