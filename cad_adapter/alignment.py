"""The numerics identity matching builds on (`cad_adapter.matching`): the rigid alignment of two point sets (RANSAC
over Kabsch fits, scored by how many placements it explains) and optimal assignments, sparse and dense, with a cost
for leaving a row unmatched. Pure numpy and scipy."""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.optimize import linear_sum_assignment
from scipy.sparse.csgraph import min_weight_full_bipartite_matching
from scipy.spatial import cKDTree


def kabsch(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """The rigid 4×4 ``T`` minimising ``sum |T p - q|²`` over point pairs (k, 3); no reflection."""
    cp, cq = p.mean(axis=0), q.mean(axis=0)
    h = (p - cp).T @ (q - cq)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
    r = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    t = np.eye(4)
    t[:3, :3] = r
    t[:3, 3] = cq - r @ cp
    return t


def apply_rigid(t: np.ndarray, p: np.ndarray) -> np.ndarray:
    return p @ t[:3, :3].T + t[:3, 3]


def robust_alignment(p: np.ndarray, q: np.ndarray, tol: float, seed: int = 0, rounds: int = 200,
                     frames: list[np.ndarray] | None = None, score=None) -> tuple[np.ndarray, int]:
    """``new_from_old`` of the model from unambiguous pairs ``p → q`` (k, 3), robust to parts moved alone.

    Candidates: the identity, a pure translation by the median shift, RANSAC triples (Kabsch), and
    ``frames`` (transforms proposed by single parts' principal axes). The candidate with most inliers
    (within ``tol``) wins; ties (pairs on one line fix no rotation about it) go to ``score(t)`` (a count
    of other parts it puts on an identical old part), then Kabsch refines on the inliers. Returns the
    transform and its number of inliers.
    """
    k = len(p)
    if k == 0:
        return np.eye(4), 0

    def inliers(t: np.ndarray) -> np.ndarray:
        return np.linalg.norm(apply_rigid(t, p) - q, axis=1) <= tol

    def spread(a: np.ndarray) -> bool:  # points that fix a rotation: not all on one line
        return len(a) >= 3 and np.linalg.svd(a - a.mean(axis=0), compute_uv=False)[1] > 10 * tol

    shift = np.eye(4)
    shift[:3, 3] = np.median(q - p, axis=0)
    candidates = [np.eye(4), shift] + list(frames or [])
    rng = np.random.default_rng(seed)
    if k >= 3:
        for _ in range(rounds if k > 3 else 1):
            idx = rng.choice(k, 3, replace=False)
            if spread(p[idx]):
                candidates.append(kabsch(p[idx], q[idx]))
    counts = [int(inliers(t).sum()) for t in candidates]
    top = max(counts)
    tied = [t for t, c in zip(candidates, counts, strict=True) if c == top]
    best = tied[0]
    if len(tied) > 1 and score is not None and not spread(p[inliers(best)]):
        best = max(tied, key=score)  # first of the best: no rotation unless the parts say so
    elif score is not None and top < k:
        # the unique parts disagree (some moved alone): let the identical parts vote too, so that two parts
        # of one sub-assembly moved away do not outvote a model that stayed where it was
        support = [c + score(t) if 2 * c >= top else -1 for t, c in zip(candidates, counts, strict=True)]
        if max(support) > top + score(best):
            best = candidates[int(np.argmax(support))]
    best_in = inliers(best)
    if spread(p[best_in]):
        refined = kabsch(p[best_in], q[best_in])
        if inliers(refined).sum() >= best_in.sum():
            best, best_in = refined, inliers(refined)
    return best, int(best_in.sum())


def placement_score(cls_old: np.ndarray, cls_new: np.ndarray, c_old: np.ndarray, c_new: np.ndarray, tol: float,
                    sample: int = 2000, seed: int = 0):
    """``score(t)``: how many of (a sample of) the parts in classes with several members land, carried back
    by ``t``, on an old part of their class. Trees are built once, on the old side."""
    rng = np.random.default_rng(seed)
    classes = {}
    for c in np.unique(cls_new[cls_new >= 0]):
        olds = np.flatnonzero(cls_old == c)
        if len(olds) > 1:
            classes[int(c)] = cKDTree(c_old[olds])
    news = np.flatnonzero(np.isin(cls_new, list(classes)))
    if len(news) > sample:
        news = rng.choice(news, sample, replace=False)

    def score(t: np.ndarray) -> int:
        back = np.linalg.inv(t)
        pts = apply_rigid(back, c_new[news])
        hits = 0
        for c in np.unique(cls_new[news]):
            m = cls_new[news] == c
            d, _ = classes[int(c)].query(pts[m], k=1)
            hits += int(np.sum(d <= tol))
        return hits

    return score


def sparse_assignment(rows: np.ndarray, cols: np.ndarray, cost: np.ndarray, n_rows: int, n_cols: int,
                      unmatched: float) -> np.ndarray:
    """Optimal partial assignment over candidate edges: ``match[r]`` = col or -1.

    Minimises the sum of the chosen edges' costs plus ``unmatched`` for every row and every column left
    out, over a sparse candidate graph (no all-pairs matrix): rows and columns each get a dummy partner
    (cost ``unmatched``), and each candidate edge (r, c) a zero-cost dummy edge (c', r') so that any
    partial matching extends to a perfect one. Costs are shifted by 1 (scipy drops explicit zeros).
    """
    match = np.full(n_rows, -1, np.int64)
    if len(rows) == 0 or n_rows == 0 or n_cols == 0:
        return match
    rows = np.asarray(rows, np.int64)
    cols = np.asarray(cols, np.int64)
    # left: real rows 0..R-1, column dummies R..R+C-1; right: real cols 0..C-1, row dummies C..C+R-1
    r_n, c_n = n_rows, n_cols
    li = np.concatenate([rows, np.arange(r_n), r_n + np.arange(c_n), r_n + cols])
    ri = np.concatenate([cols, c_n + np.arange(r_n), np.arange(c_n), c_n + rows])
    w = np.concatenate([np.asarray(cost, float), np.full(r_n, unmatched), np.full(c_n, unmatched),
                        np.zeros(len(rows))]) + 1.0
    g = sparse.coo_matrix((w, (li, ri)), shape=(r_n + c_n, r_n + c_n)).tocsr()
    g.sum_duplicates()
    left, right = min_weight_full_bipartite_matching(g)
    del left
    pairs = right[:r_n]
    ok = pairs < c_n
    match[ok] = pairs[ok]
    return match


def dense_assignment(cost: np.ndarray, unmatched: float) -> np.ndarray:
    """``match[r]`` for a small dense cost matrix with a cost for leaving a row or column out."""
    r, c = cost.shape
    big = np.full((r + c, c + r), 0.0)
    big[:r, :c] = cost
    big[:r, c:] = np.where(np.eye(r, dtype=bool), unmatched, np.inf)
    big[r:, :c] = np.where(np.eye(c, dtype=bool), unmatched, np.inf)
    big[np.isinf(big)] = 1e18
    ri, ci = linear_sum_assignment(big)
    match = np.full(r, -1, np.int64)
    for a, b in zip(ri, ci, strict=True):
        if a < r and b < c:
            match[a] = b
    return match
