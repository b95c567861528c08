"""The bottom levels' rows as traversal reads them: child-box rows (`pack_rows`, 64-byte float32 rows, rounded
outward) and the 4-wide quantised rows made from them (`widen`, `pack_wide`: four boxes to 8 bits in one 64-byte
row), the float32 rounding helpers (`down32`, `up32`) and the triangles in leaf order (`leaf_order_f32`).

`tracer.accel.blas` builds the trees these rows come from; `tracer.accel.tlas` packs the top level with
`pack_rows` too.
"""

from __future__ import annotations

import math

import numpy as np

from tracer.jit import njit


@njit(cache=True, error_model="numpy")
def down32(x):
    """Largest float32 <= x (x finite or infinite). Without a branch (both candidates, then a select): a
    ray's setup rounds several values (:func:`tracer.accel.rows8.ray8`), whose outcome no predictor can guess."""
    f = np.float32(x)
    g = np.float32(x - abs(x) * 2.5e-7 - 1e-38)
    return g if np.float64(f) > x else f


@njit(cache=True, error_model="numpy")
def up32(x):
    """Smallest float32 >= x (branch-free, as :func:`down32`)."""
    f = np.float32(x)
    g = np.float32(x + abs(x) * 2.5e-7 + 1e-38)
    return g if np.float64(f) < x else f


@njit(cache=True, error_model="numpy")
def _pack_rows(boxes, refs, out_f, out_i):
    for r in range(boxes.shape[0]):
        for c in range(2):
            for a in range(3):
                out_f[r, 6 * c + a] = down32(boxes[r, 6 * c + a])
                out_f[r, 6 * c + 3 + a] = up32(boxes[r, 6 * c + 3 + a])
        out_i[r, 12] = refs[r, 0]
        out_i[r, 13] = refs[r, 1]
        out_i[r, 14] = 0
        out_i[r, 15] = 0


def pack_rows(boxes: np.ndarray, refs: np.ndarray) -> np.ndarray:
    """(R, 16) float32 traversal rows: the 12 box values rounded outward to float32, then the two
    child references bit-cast into columns 12-13 (read through an int32 view of the same buffer)."""
    out = np.empty((len(boxes), 16), np.float32)
    _pack_rows(boxes, refs, out, out.view(np.int32))
    return out


def aligned_rows(n: int) -> np.ndarray:
    """Uninitialised (n, 16) float32 rows starting on a 64-byte boundary, so a row is one cache line
    (numpy only promises 16 bytes: most rows would straddle two lines)."""
    buf = np.empty(n * 64 + 64, np.uint8)
    off = (-buf.ctypes.data) % 64
    return buf[off:off + n * 64].view(np.float32).reshape(n, 16)


@njit(cache=True, error_model="numpy")
def widen(boxes, refs, row_cnt):
    """Collapse the binary child-box rows of each geometry (:func:`collapse`) into 4-wide rows.

    A wide row holds the grandchildren of a binary row (a child that is a leaf stays a child), so
    each wide level skips a binary level: a ray fetches about half as many rows and tests four boxes
    at once (:func:`tracer.accel.wide.slab4`). Empty slots get an empty box and reference -1.

    Returns ``wboxes`` (W, 24) float64, SoA planes ``wboxes[w, 4 a + c]`` (``a`` = xmin, ymin, zmin,
    xmax, ymax, zmax; ``c`` the slot), ``wrefs`` (W, 4) int64 (as in :func:`collapse`, rows now wide
    rows local to the geometry) and ``wcnt`` (G,) int64, wide rows per geometry.
    """
    g_n = row_cnt.shape[0]
    total = boxes.shape[0]
    wboxes = np.empty((total, 24))
    wrefs = np.empty((total, 4), np.int64)
    wcnt = np.zeros(g_n, np.int64)
    queue = np.empty(total + 1, np.int64)
    b0 = 0
    w0 = 0
    for g in range(g_n):
        n = row_cnt[g]
        if n == 0:
            continue
        queue[0] = 0
        nw = 1
        k = 0
        while k < nw:
            b = b0 + queue[k]
            row = w0 + k
            slot = 0
            for c in range(2):
                ref = refs[b, c]
                if ref >= 0:
                    for cc in range(2):
                        r2 = refs[b0 + ref, cc]
                        for a in range(6):
                            wboxes[row, 4 * a + slot] = boxes[b0 + ref, 6 * cc + a]
                        if r2 >= 0:
                            queue[nw] = r2
                            wrefs[row, slot] = nw
                            nw += 1
                        else:
                            wrefs[row, slot] = r2
                        slot += 1
                else:
                    for a in range(6):
                        wboxes[row, 4 * a + slot] = boxes[b, 6 * c + a]
                    wrefs[row, slot] = ref
                    slot += 1
            while slot < 4:
                for a in range(3):
                    wboxes[row, 4 * a + slot] = np.inf
                    wboxes[row, 4 * (a + 3) + slot] = -np.inf
                wrefs[row, slot] = -1
                slot += 1
            k += 1
        wcnt[g] = nw
        b0 += n
        w0 += nw
    return wboxes[:w0], wrefs[:w0], wcnt


@njit(cache=True, error_model="numpy")
def _fits(origin, scale, lo, hi):
    """Quantised planes ``(qlo, qhi)`` enclosing ``[lo, hi]`` on the grid ``origin + q scale``, or
    ``(-1, -1)`` when 255 steps do not reach ``hi``. The tests compute ``origin + q scale`` as traversal
    does (float64; the product is exact, so a fused multiply-add gives the same), so they hold for the
    very planes traversal tests."""
    qlo = min(max(np.int64(math.floor((lo - origin) / scale)), 0), 255)
    while qlo > 0 and origin + qlo * scale > lo:
        qlo -= 1
    qhi = min(max(np.int64(math.ceil((hi - origin) / scale)), 0), 255)
    while qhi < 255 and origin + qhi * scale < hi:
        qhi += 1
    if origin + qhi * scale < hi or origin + qlo * scale > lo:
        return -1, -1
    return qlo, qhi


@njit(cache=True, error_model="numpy")
def _quantize(wboxes, out_f, out_b):
    """Write the boxes ``wboxes[w]`` (as from :func:`widen`) quantised into row ``w``."""
    for w in range(wboxes.shape[0]):
        for a in range(3):
            lo = np.inf
            hi = -np.inf
            for c in range(4):
                if wboxes[w, 4 * a + c] <= wboxes[w, 4 * (a + 3) + c]:
                    lo = min(lo, wboxes[w, 4 * a + c])
                    hi = max(hi, wboxes[w, 4 * (a + 3) + c])
            if lo > hi:   # no child box (widen gives every row one; kept safe): an empty grid
                lo = 0.0
                hi = 0.0
            origin = np.float64(down32(lo))
            ext = np.float64(up32(hi)) - origin
            # smallest power of two with 255 steps covering ext, not below origin's float32 ulp / 2^20
            # (keeps origin + q scale exact in float64) nor float32's normal range
            e = math.frexp(ext / 255.0)[1] if ext > 0.0 else -126
            if origin != 0.0:
                e = max(e, math.frexp(abs(origin))[1] - 44)
            e = max(e, -126)
            while True:
                scale = math.ldexp(1.0, e)
                ok = True
                for c in range(4):
                    if wboxes[w, 4 * a + c] <= wboxes[w, 4 * (a + 3) + c]:
                        qlo, qhi = _fits(origin, scale, wboxes[w, 4 * a + c], wboxes[w, 4 * (a + 3) + c])
                        if qlo < 0:
                            ok = False
                            break
                if ok:
                    break
                e += 1
            out_f[w, a] = np.float32(origin)
            out_f[w, 3 + a] = np.float32(scale)
            for c in range(4):
                if wboxes[w, 4 * a + c] <= wboxes[w, 4 * (a + 3) + c]:
                    qlo, qhi = _fits(origin, scale, wboxes[w, 4 * a + c], wboxes[w, 4 * (a + 3) + c])
                else:   # empty slot: an inverted box, never entered on this axis
                    qlo, qhi = 255, 0
                out_b[w, 24 + 4 * a + c] = np.uint8(qlo)
                out_b[w, 24 + 4 * (a + 3) + c] = np.uint8(qhi)


def pack_wide(boxes: np.ndarray, refs: np.ndarray, row_cnt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """4-wide quantised traversal rows from binary child-box rows (:func:`collapse`).

    One 64-byte row (one cache line) per wide node: float32 ``origin`` (x, y, z) and power-of-two
    ``scale`` (x, y, z) in columns 0-5; bytes 24-47 the four children's boxes as 8-bit grid steps,
    planes of four (xmin, ymin, zmin, xmax, ymax, zmax: byte ``24 + 4 plane + slot``), each rounded
    outward so the box encloses the child's exact box; the four child references (int32) in columns
    12-15. A binary row takes 64 bytes for two children, a wide row for four: half the memory traffic
    of the binary layout per box tested (Ylitie, Karras and Laine, HPG 2017, compress the same way).

    Returns the (W, 16) float32 rows (64-byte aligned) and the wide rows per geometry.
    """
    wboxes, wrefs, wcnt = widen(boxes, refs, row_cnt)
    out = aligned_rows(len(wboxes))
    _quantize(wboxes, out, out.view(np.uint8))
    out.view(np.int32)[:, 12:16] = wrefs
    return out, wcnt


@njit(cache=True, error_model="numpy")
def leaf_order_f32(tri_v, leaf_rows):
    """``tri_v[leaf_rows]`` as a flat float32 array (exact: the coordinates are float32 values)."""
    out = np.empty(9 * leaf_rows.shape[0], np.float32)
    for j in range(leaf_rows.shape[0]):
        r = leaf_rows[j]
        for c in range(9):
            out[9 * j + c] = tri_v[r, c]
    return out
