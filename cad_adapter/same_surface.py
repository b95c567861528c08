"""Whether two meshes show the same surface within a tolerance: the symmetric Hausdorff distance, decided.

Two tessellations of B-reps that are the same within the document's tolerance (a writer split an edge, renumbered
its entities) differ in their triangles, not in their surface: every point of either lies within the
tessellation's deflection of the other. :func:`within` decides ``H(a, b) <= tol`` for the symmetric Hausdorff
distance between the surfaces, probed at every vertex, every triangle's centroid and every edge's midpoint of
each mesh, with exact point-to-triangle distances (Ericson's closest point on a triangle). Candidates come from a
KD-tree over the other mesh's triangle centroids (k nearest), with a bounded brute-force pass over the triangles
whose box, grown by ``tol``, holds the point where those fail; the first point proven farther than ``tol`` ends
the test, so a real change costs little. numpy and scipy only.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

#: candidates per probe point from the KD-tree before the exhaustive pass
NEIGHBOURS = 16


def closest_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Distance from each point ``p[i]`` to the triangle ``(a[i], b[i], c[i])`` (all (k, 3) float64)."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap)
    bp = p - b
    d3, d4 = np.einsum("ij,ij->i", ab, bp), np.einsum("ij,ij->i", ac, bp)
    cp = p - c
    d5, d6 = np.einsum("ij,ij->i", ab, cp), np.einsum("ij,ij->i", ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        v = np.where(denom != 0, vb / denom, 0.0)
        w = np.where(denom != 0, vc / denom, 0.0)
        q = a + ab * v[:, None] + ac * w[:, None]  # inside the face
        # edges and vertices (Ericson, Real-Time Collision Detection 5.1.5), last assignment wins
        t_ab = np.where(d1 - d3 != 0, d1 / (d1 - d3), 0.0)
        on_ab = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
        q = np.where(on_ab[:, None], a + ab * t_ab[:, None], q)
        t_ac = np.where(d2 - d6 != 0, d2 / (d2 - d6), 0.0)
        on_ac = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
        q = np.where(on_ac[:, None], a + ac * t_ac[:, None], q)
        t_bc = np.where((d4 - d3) + (d5 - d6) != 0, (d4 - d3) / ((d4 - d3) + (d5 - d6)), 0.0)
        on_bc = (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0)
        q = np.where(on_bc[:, None], b + (c - b) * t_bc[:, None], q)
    q = np.where(((d1 <= 0) & (d2 <= 0))[:, None], a, q)
    q = np.where(((d3 >= 0) & (d4 <= d3))[:, None], b, q)
    q = np.where(((d6 >= 0) & (d5 <= d6))[:, None], c, q)
    return np.linalg.norm(p - q, axis=1)


def probes(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """The points a mesh is probed at: its vertices, triangle centroids and edge midpoints."""
    v = np.asarray(vertices, np.float64)
    t = np.asarray(triangles, np.int64)
    tri = v[t]
    mids = np.concatenate([(tri[:, 0] + tri[:, 1]) / 2, (tri[:, 1] + tri[:, 2]) / 2, (tri[:, 2] + tri[:, 0]) / 2])
    return np.concatenate([v, tri.mean(axis=1), np.unique(mids, axis=0)])


def _one_way(points: np.ndarray, vertices: np.ndarray, triangles: np.ndarray, tol: float) -> float:
    """The largest distance from ``points`` to the mesh, if it is at most ``tol``; else a distance beyond ``tol``
    (the first found)."""
    v = np.asarray(vertices, np.float64)
    tri = v[np.asarray(triangles, np.int64)]
    lo, hi = tri.min(axis=1) - tol, tri.max(axis=1) + tol
    tree = cKDTree(tri.mean(axis=1))
    k = min(NEIGHBOURS, len(tri))
    worst = 0.0
    for start in range(0, len(points), 4096):
        p = points[start:start + 4096]
        _, idx = tree.query(p, k=k)
        idx = idx.reshape(len(p), k)
        d = closest_on_triangles(np.repeat(p, k, axis=0), *(tri[idx.ravel(), j] for j in range(3))).reshape(len(p), k)
        best = d.min(axis=1)
        for i in np.flatnonzero(best > tol):  # the k nearest centroids missed it: every triangle whose box holds it
            cand = np.flatnonzero(np.all((lo <= p[i]) & (p[i] <= hi), axis=1))
            if len(cand) == 0:
                return float(best[i])
            best[i] = min(best[i], float(closest_on_triangles(np.repeat(p[i:i + 1], len(cand), axis=0),
                                                              tri[cand, 0], tri[cand, 1], tri[cand, 2]).min()))
            if best[i] > tol:
                return float(best[i])
        worst = max(worst, float(best.max(initial=0.0)))
    return worst


def hausdorff_within(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray], tol: float) -> float:
    """The symmetric Hausdorff distance between meshes ``a`` and ``b`` (each ``(vertices, triangles)``), probed
    as the module says, when it is at most ``tol``; otherwise some distance beyond ``tol`` (not the largest).

    Raises
    ------
    ValueError
        ``tol`` is not a finite number >= 0, or a mesh has no triangle.
    """
    if not (isinstance(tol, int | float) and np.isfinite(tol) and tol >= 0):
        raise ValueError(f"tol must be a finite number >= 0, got {tol!r}")
    for name, (v, t) in (("a", a), ("b", b)):
        if len(t) == 0 or len(v) == 0:
            raise ValueError(f"mesh {name} has no triangle")
    ab = _one_way(probes(*a), *b, tol)
    if ab > tol:
        return ab
    return max(ab, _one_way(probes(*b), *a, tol))


def within(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray], tol: float) -> bool:
    """Whether the two meshes' surfaces lie within ``tol`` of each other (symmetric Hausdorff)."""
    return hausdorff_within(a, b, tol) <= tol
