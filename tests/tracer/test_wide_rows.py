"""The 4-wide quantised rows (tracer.blas.pack_wide): every stored box encloses its child's exact box,
whatever the coordinates' magnitude, and a refitted top level equals one widened afresh."""

from __future__ import annotations

import numpy as np
import pytest

from tracer import tlas
from tracer.blas import build_meshes, collapse, gather_triangles, pack_wide, widen


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
    wboxes, wrefs, _, _ = widen(boxes, refs, cnt)
    rows, wcnt, _ = pack_wide(boxes, refs, cnt)
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


def test_refitted_top_level_equals_a_fresh_widening() -> None:
    rng = np.random.default_rng(3)
    n = 500
    lo = rng.uniform(-10, 10, (n, 3))
    boxes = np.concatenate([lo, lo + rng.uniform(0.01, 1, (n, 3))], axis=1)
    level = tlas.build_top(np.arange(n), boxes)
    moved = rng.choice(n, 20, replace=False)
    boxes[moved, :3] += 5.0
    boxes[moved, 3:] += 5.0
    refitted = tlas.refit_top(level, moved.astype(np.int64), boxes)
    assert not np.array_equal(refitted.wide, level.wide)   # it did change, and the old arrays are kept
    b = refitted.binary
    fresh, _, _ = pack_wide(b[:, :12].astype(np.float64), b.view(np.int32)[:, 12:14].astype(np.int64),
                            np.array([len(b)], np.int64))
    assert np.array_equal(refitted.wide.view(np.uint8), fresh.view(np.uint8))
