"""Supports of any outline: which features lie wholly on a planar support that is not a rectangle (a round light
guide, a lens face, a plate with a hole), as a raster mask the inner tracer reads.

A layout covers the support's u-v box (`tracer.elements.support.Frame`); where the support is not that whole box,
a feature is placed only where its base (a disc of the feature's half base ``a`` around its centre) lies wholly on
the support's triangles. The rule is kept as a bitmap over the box (at most `RESOLUTION` cells a side, cell ``h``
mm): a cell is kept where its centre is on the support (even-odd crossings of the outline's edges along the cell
row) and at least ``a + sqrt(2) h`` from the outline (a distance transform of the cells the outline crosses), so
that a feature centred anywhere in a kept cell lies on the support. The price of the raster: a feature whose base
comes within ``2 sqrt(2) h`` of the outline may be left out (0.04 mm on a 20 mm guide). A support that is its box
needs no mask: its answers are bit-for-bit those of before.
"""

from __future__ import annotations

import math

import numpy as np

RESOLUTION = 1024


def boundary(tri_uv: np.ndarray) -> np.ndarray:
    """The outline's edges (E, 2, 2) mm: the edges of the triangles (T, 3, 2) that only one of them has (corners at
    one position, to 1e-9 of the extent, are one corner: a CAD mesh repeats them across its faces)."""
    pts = tri_uv.reshape(-1, 2)
    extent = float(np.ptp(pts, axis=0).max())
    _, corner = np.unique(np.round(pts / (1e-9 * extent)), axis=0, return_inverse=True)
    corner = corner.ravel().reshape(-1, 3)
    a = corner.ravel()
    b = np.roll(corner, -1, axis=1).ravel()
    key = np.minimum(a, b) * (int(corner.max()) + 1) + np.maximum(a, b)
    _, inverse, counts = np.unique(key, return_inverse=True, return_counts=True)
    lonely = counts[inverse.ravel()] == 1
    starts = tri_uv.reshape(-1, 2)
    ends = np.roll(tri_uv, -1, axis=1).reshape(-1, 2)
    return np.stack([starts[lonely], ends[lonely]], axis=1)


def mask(tri_uv: np.ndarray, lu: float, lv: float, a: float) -> tuple[np.ndarray, int, int, float]:
    """``(bits, nu, nv, h)``: the kept cells of the support's u-v box [0, lu] x [0, lv] (mm), row by row along v,
    one bit each (little-endian), for features of half base `a` (mm); ``h`` the cell's side (mm)."""
    from scipy.ndimage import distance_transform_edt

    h = max(lu, lv) / RESOLUTION
    nu, nv = max(1, math.ceil(lu / h)), max(1, math.ceil(lv / h))
    edges = boundary(tri_uv)
    inside = _inside(edges, nu, nv, h)
    crossed = np.zeros((nv, nu), bool)
    length = np.linalg.norm(edges[:, 1] - edges[:, 0], axis=1)
    for k in range(len(edges)):   # each edge sampled every h / 4: every cell it crosses is marked
        t = np.linspace(0.0, 1.0, max(2, int(math.ceil(4 * length[k] / h)) + 1))
        p = edges[k, 0] + t[:, None] * (edges[k, 1] - edges[k, 0])
        i = np.clip((p[:, 0] / h).astype(np.int64), 0, nu - 1)
        j = np.clip((p[:, 1] / h).astype(np.int64), 0, nv - 1)
        crossed[j, i] = True
    far = distance_transform_edt(~crossed) * h >= a + math.sqrt(2.0) * h
    kept = inside & far
    return np.packbits(kept.ravel(), bitorder="little"), nu, nv, h


def _inside(edges: np.ndarray, nu: int, nv: int, h: float) -> np.ndarray:
    """(nv, nu) whether each cell's centre is on the support: the outline's crossings of the cell row's centre line,
    counted from the left (even-odd: holes are outside)."""
    y = (np.arange(nv) + 0.5) * h
    x = (np.arange(nu) + 0.5) * h
    (x0, y0), (x1, y1) = edges[:, 0].T, edges[:, 1].T
    inside = np.zeros((nv, nu), bool)
    for j0 in range(0, nv, 64):
        yy = y[j0:j0 + 64, None]
        spans = (y0 <= yy) != (y1 <= yy)                                   # (rows, E): the edge crosses the row
        with np.errstate(divide="ignore", invalid="ignore"):
            xc = np.where(spans, x0 + (yy - y0) * (x1 - x0) / (y1 - y0), np.inf)
        xc.sort(axis=1)
        for r, row in enumerate(xc):
            inside[j0 + r] = np.searchsorted(row[np.isfinite(row)], x) % 2 == 1   # crossings left of each cell
    return inside
