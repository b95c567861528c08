"""Reconciling a document's tree with the tree held before: which new node is which old node.

Pure arrays (numpy, scipy), no CAD kernel: the old side comes from the scene (``GET /scenes/{id}/nodes``)
or the sidecar, the new side from the document just read. Both are :class:`Side` records.

Matching is a global assignment, never nearest-first. The rules, in order (``Reconciliation.rule``):

``carried``    the document carries the UUID (cadquery metadata, a STEP id).
``shape``      a shape class (leaves: volume, area, principal moments, topology, all frame-independent;
               assemblies: the multiset of their children's classes) with exactly one old and one new
               member. These unambiguous pairs also give the rigid alignment of the whole model.
``placement``  identical parts (or identical sub-assemblies): an optimal assignment
               (``scipy.sparse.csgraph.min_weight_full_bipartite_matching``) on the distance between the
               new centroid and the old one carried by the alignment (RANSAC + Kabsch over the ``shape``
               pairs, so a model turned as a whole keeps every part's UUID).
``structure``  an assembly whose children's old parent is one node (votes, then an assignment); a
               reshaped part under a matched parent, by its placement in that parent and its product name.
``path``       the same occurrence path (names from the root) as an unmatched old node.
``restored``   a node the scene removed earlier (its memory of removed nodes, ``GET /scenes/{id}/removed-nodes``)
               that comes back within tolerance: a part of the same shape class whose centroid, carried by the
               model's alignment, lies within the alignment's tolerance of where it was; an assembly whose
               restored children mostly belonged to one removed assembly of the same name or placement.
``new``        a fresh UUID.

A pair is *ambiguous* only when another identical part truly ties with it: taking that part instead (a free
one, or swapping with the new part that holds it) costs no more, within the tolerance (``TIE_RTOL`` of the
diagonal), than the optimal assignment's choice; or when its instance name names another old part of the same
class (two identical parts swapped). A part that moved far but still has one clear best match is not ambiguous. It keeps
the UUID the placement gives, and is reported with its candidates: never a silent guess.
"""

from __future__ import annotations

import uuid as uuidlib
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from cad_adapter.alignment import (
    apply_rigid,
    dense_assignment,
    placement_score,
    robust_alignment,
    sparse_assignment,
)
from cad_adapter.sides import CLASS_RTOL, ShapeKey, Side, is_writer_id

RULES = ("carried", "shape", "placement", "structure", "path", "restored", "new")
#: a node moved less than this fraction of the model's diagonal (after alignment) sits where it was
SAME_PLACE_RTOL = 1e-6
#: two candidates tie when taking the other costs no more than this fraction of the diagonal (plus the
#: same-place tolerance): only then is a match ambiguous
TIE_RTOL = 1e-6
@dataclass
class Reconciliation:
    """Which old row each new row is (``old[i]``, -1 if none), the UUID it gets, and why.

    Attributes
    ----------
    old : (n_new,) int64
    uuids : list of str
    rule : list of str
        One of :data:`RULES` per new row.
    ambiguous : list of dict
        ``{"row", "path", "uuid", "candidates": [uuid, ...], "reason"}`` per ambiguous new row.
    alignment : (4, 4) float64
        ``new_from_old`` of the model as a whole.
    alignment_inliers : int
        Unambiguous pairs that agree with the alignment.
    restored : (n_new,) int64
        The row of ``removed`` (reconcile's argument) each new row took its UUID from, -1 if none.
    """

    old: np.ndarray
    uuids: list[str]
    rule: list[str]
    ambiguous: list[dict] = field(default_factory=list)
    alignment: np.ndarray = field(default_factory=lambda: np.eye(4))
    alignment_inliers: int = 0
    restored: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    def counts(self) -> dict[str, int]:
        out = dict.fromkeys(RULES, 0)
        for r in self.rule:
            out[r] += 1
        return out


# ---------------------------------------------------------------- classes

def shape_classes(keys: Sequence[ShapeKey | None], rtol: float = CLASS_RTOL) -> np.ndarray:
    """A class id per key (-1 for None): keys equal within ``rtol`` share one.

    Sorted by volume and swept with a window of open classes, so near-linear in the number of keys.
    """
    out = np.full(len(keys), -1, np.int64)
    order = sorted((i for i, k in enumerate(keys) if k is not None), key=lambda i: keys[i].volume)  # type: ignore[union-attr]
    reps: list[tuple[ShapeKey, int]] = []  # (representative, class) of the classes open in the window
    n_classes = 0
    for i in order:
        k = keys[i]
        assert k is not None
        window = rtol * (abs(k.volume) + k.size ** 3) * 2
        reps = [(r, c) for r, c in reps if k.volume - r.volume <= window]
        for r, c in reps:
            if k.matches(r, rtol):
                out[i] = c
                break
        else:
            out[i] = n_classes
            reps.append((k, n_classes))
            n_classes += 1
    return out


def content_classes(old: Side, new: Side) -> tuple[np.ndarray, np.ndarray]:
    """Class ids over both sides: leaves by shape, assemblies by the multiset of their children's classes."""
    leaf_cls = shape_classes(list(old.keys) + list(new.keys))
    intern: dict[tuple, int] = {}
    out = []
    for side, base in ((old, 0), (new, len(old))):
        cls = np.full(len(side), -1, np.int64)
        children: list[list[int]] = [[] for _ in range(len(side))]
        for i in range(len(side) - 1, -1, -1):
            if side.leaf[i]:
                c = leaf_cls[base + i]
                key: tuple = ("part", int(c)) if c >= 0 else ("empty", side.products[i] or side.names[i])
            else:
                key = ("assembly", tuple(sorted(children[i])))
            cls[i] = intern.setdefault(key, len(intern))
            p = side.parent[i]
            if p >= 0:
                children[p].append(int(cls[i]))
        out.append(cls)
    return out[0], out[1]


def world_centroids(side: Side) -> np.ndarray:
    """(n, 3): a leaf's centroid in the world; an assembly's, the mean over its leaves (frame-independent)."""
    n = len(side)
    if n == 0:
        return np.zeros((0, 3))
    c = np.einsum("nij,nj->ni", side.world[:, :3, :3], side.centroid) + side.world[:, :3, 3]
    total = np.where(side.leaf[:, None], c, 0.0)
    count = side.leaf.astype(np.float64).copy()
    for i in range(n - 1, -1, -1):
        p = side.parent[i]
        if p >= 0:
            total[p] += total[i]
            count[p] += count[i]
    has = count > 0
    c[has] = total[has] / count[has, None]
    return c


# ---------------------------------------------------------------- alignment


def frame_candidates(old: Side, new: Side, pairs: list[tuple[int, int]], c_old: np.ndarray,
                     c_new: np.ndarray, limit: int = 16) -> list[np.ndarray]:
    """Transforms that carry one unambiguous part's principal frame onto its new one (4 sign choices each).

    Only parts whose three principal moments differ (otherwise the axes are not defined)."""
    if old.axes is None or new.axes is None:
        return []
    out = []
    for i, j in pairs[:limit]:
        key = new.keys[i]
        if key is None or not np.any(new.axes[i]) or not np.any(old.axes[j]):
            continue
        m = np.asarray(key.moments)
        if min(m[1] - m[0], m[2] - m[1]) <= 1e-3 * max(m[2], 1e-300):
            continue
        a_old = old.world[j, :3, :3] @ old.axes[j].T  # columns: the principal axes in the world
        a_new = new.world[i, :3, :3] @ new.axes[i].T
        for signs in ((1, 1, 1), (1, -1, -1), (-1, 1, -1), (-1, -1, 1)):
            r = (a_new * np.array(signs)) @ a_old.T
            if np.linalg.det(r) < 0:
                continue
            t = np.eye(4)
            t[:3, :3] = r
            t[:3, 3] = c_new[i] - r @ c_old[j]
            out.append(t)
    return out


# ---------------------------------------------------------------- assignment


# ---------------------------------------------------------------- the reconciliation

class _State:
    def __init__(self, old: Side, new: Side) -> None:
        self.old, self.new = old, new
        self.match = np.full(len(new), -1, np.int64)  # new row -> old row
        self.taken = np.zeros(len(old), bool)
        self.rule: list[str] = ["new"] * len(new)
        self.ambiguous: dict[int, dict] = {}

    def bind(self, i: int, j: int, rule: str) -> None:
        self.match[i] = j
        self.taken[j] = True
        self.rule[i] = rule

    def free_new(self) -> np.ndarray:
        return self.match < 0

    def free_old(self) -> np.ndarray:
        return ~self.taken


def _groups(cls: np.ndarray, mask: np.ndarray) -> dict[int, np.ndarray]:
    idx = np.flatnonzero(mask & (cls >= 0))
    if len(idx) == 0:
        return {}
    order = np.argsort(cls[idx], kind="stable")
    idx = idx[order]
    values, starts = np.unique(cls[idx], return_index=True)
    return {int(v): g for v, g in zip(values, np.split(idx, starts[1:]), strict=True)}


def reconcile(old: Side, new: Side, *, diagonal: float | None = None, same_place_rtol: float = SAME_PLACE_RTOL,
              neighbours: int = 8, seed: int = 0, removed: Side | None = None) -> Reconciliation:
    """Match the rows of ``new`` to those of ``old`` (see the module docstring for the rules).

    Parameters
    ----------
    old, new : Side
        In the same length unit.
    diagonal : float, optional
        The model's size (document units); default the diagonal of both sides' centroids' box.
    same_place_rtol : float
        A centroid within this fraction of ``diagonal`` (after alignment) has not moved.
    neighbours : int
        Candidates per node among identical parts (k nearest after alignment).
    removed : Side, optional
        Nodes the scene removed earlier (same unit): new nodes that match nothing in ``old`` and come back
        where one of them was get its UUID (rule ``restored``; ``Reconciliation.restored`` gives the row).
    """
    st = _State(old, new)
    c_old, c_new = world_centroids(old), world_centroids(new)
    if diagonal is None:
        diagonal = _default_diagonal(c_old, c_new)
    tol_same = same_place_rtol * diagonal

    # 1. carried UUIDs (a UUID carried twice is trusted once: the first, in document order)
    carried = _bind_carried(st)

    # 2. classes; 1:1 classes are unambiguous pairs and give the alignment
    cls_old, cls_new = content_classes(old, new)
    g_old, g_new = _bind_unique_classes(st, cls_old, cls_new, carried)
    tol_align = max(1e-4 * diagonal, 10 * tol_same)
    align, n_in = _align_model(st, cls_old, cls_new, c_old, c_new, tol_align, seed)
    c_old_aligned = apply_rigid(align, c_old) if len(old) else c_old

    # 3. identical parts and identical sub-assemblies: optimal assignment on aligned distance
    _assign_identical(st, g_old, g_new, c_new, c_old_aligned, diagonal, tol_same, neighbours)

    # 4. structure: assemblies by their children's old parents; reshaped parts by parent and placement
    for _ in range(2):
        _assemblies_by_votes(st)
        _reshaped_by_parent(st, diagonal)
    _assemblies_by_votes(st)
    # 5. nodes removed earlier that come back where they were
    restored = np.full(len(new), -1, np.int64)
    if removed is not None and len(removed):
        restored = _restore(st, removed, c_new, align, max(tol_align, tol_same), diagonal)
    # 6. occurrence path, then lone roots
    _bind_by_path(st)
    _bind_lone_roots(st)

    uuids = _final_uuids(st, restored, removed)
    ambiguous = []
    for i, a in sorted(st.ambiguous.items()):
        if st.match[i] >= 0 or restored[i] >= 0:
            ambiguous.append({"row": i, "path": new.paths[i], "uuid": uuids[i], **a})
    return Reconciliation(st.match, uuids, st.rule, ambiguous, align, n_in, restored)


def _default_diagonal(c_old: np.ndarray, c_new: np.ndarray) -> float:
    """The diagonal of both sides' centroids' box: the model's size that every tolerance scales with (1 if none)."""
    pts = np.concatenate([c_old, c_new]) if len(c_old) + len(c_new) else np.zeros((1, 3))
    return float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))) or 1.0


def _bind_carried(st: _State) -> np.ndarray:
    """Rule ``carried``: the document's own UUID wins over any evidence (the first carrier only, since a copy may
    carry it too); the mask of rows that carry one, matched in ``old`` or not."""
    old_index = {u: j for j, u in enumerate(st.old.uuids) if u}
    seen: set[str] = set()
    for i, u in enumerate(st.new.uuids):
        if u and u not in seen:
            seen.add(u)
            j = old_index.get(u, -1)
            st.rule[i] = "carried"
            if j >= 0 and not st.taken[j]:
                st.match[i] = j
                st.taken[j] = True
    return np.array([r == "carried" for r in st.rule], bool)


def _bind_unique_classes(st: _State, cls_old: np.ndarray, cls_new: np.ndarray,
                         carried: np.ndarray) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray]]:
    """Rule ``shape``: a class with one old and one new member is a pair no placement can dispute; answers the
    classes' (old, new) groups, taken before these pairs so the identical parts' step sees the same groups."""
    g_old = _groups(cls_old, ~st.taken)
    g_new = _groups(cls_new, ~carried)
    anchors = [(int(g_new[c][0]), int(g_old[c][0])) for c in g_new if c in g_old
               and len(g_new[c]) == 1 and len(g_old[c]) == 1]
    for i, j in anchors:
        st.bind(i, j, "shape")
    return g_old, g_new


def _align_model(st: _State, cls_old: np.ndarray, cls_new: np.ndarray, c_old: np.ndarray, c_new: np.ndarray,
                 tol_align: float, seed: int) -> tuple[np.ndarray, int]:
    """The model's rigid motion (``new_from_old``, inliers) from the pairs bound so far, so a model turned as a
    whole keeps its identical parts' UUIDs."""
    old, new = st.old, st.new
    pairs = [(i, j) for i, j in enumerate(st.match) if j >= 0]
    p = np.array([c_old[j] for _, j in pairs]).reshape(-1, 3)
    q = np.array([c_new[i] for i, _ in pairs]).reshape(-1, 3)
    return robust_alignment(p, q, tol=tol_align, seed=seed,
                            frames=frame_candidates(old, new, pairs, c_old, c_new),
                            score=placement_score(cls_old, cls_new, c_old, c_new, tol_align, seed=seed))


def _assign_identical(st: _State, g_old: dict[int, np.ndarray], g_new: dict[int, np.ndarray], c_new: np.ndarray,
                      c_old_aligned: np.ndarray, diagonal: float, tol_same: float, neighbours: int) -> None:
    """Rule ``placement``: per class of several members, the still free rows assigned on aligned distance."""
    for c, news in g_new.items():
        olds = g_old.get(c)
        if olds is None or (len(news) == 1 and len(olds) == 1):
            continue
        news = news[st.match[news] < 0]
        olds = olds[~st.taken[olds]]
        if len(news) == 0 or len(olds) == 0:
            continue
        _assign_by_place(st, news, olds, c_new, c_old_aligned, diagonal, tol_same, neighbours)


def _bind_by_path(st: _State) -> None:
    """Rule ``path``: a node no evidence placed keeps the UUID of the free old node at its occurrence path (the
    first such in document order), if both are leaves or both assemblies."""
    old, new = st.old, st.new
    free_old_paths: dict[str, int] = {}
    for j in np.flatnonzero(~st.taken):
        free_old_paths.setdefault(old.paths[j], int(j))
    for i in np.flatnonzero(st.match < 0):
        if st.rule[i] in ("carried", "restored"):
            continue
        j = free_old_paths.get(new.paths[i], -1)
        if j >= 0 and not st.taken[j] and bool(old.leaf[j]) == bool(new.leaf[i]):
            st.bind(int(i), j, "path")


def _bind_lone_roots(st: _State) -> None:
    """Rule ``structure`` for the roots: one free assembly root on each side is the same document's root."""
    old, new = st.old, st.new
    roots_new = [i for i in np.flatnonzero(new.parent < 0) if st.match[i] < 0 and st.rule[i] not in ("carried",
                                                                                                  "restored")]
    roots_old = [j for j in np.flatnonzero(old.parent < 0) if not st.taken[j]]
    if len(roots_new) == 1 and len(roots_old) == 1 and not new.leaf[roots_new[0]] and not old.leaf[roots_old[0]]:
        st.bind(int(roots_new[0]), int(roots_old[0]), "structure")


def _final_uuids(st: _State, restored: np.ndarray, removed: Side | None) -> list[str]:
    """The UUID of each new row: its carried one, its match's, its restored node's, else a fresh one."""
    old, new = st.old, st.new
    uuids = []
    for i in range(len(new)):
        if st.rule[i] == "carried":
            uuids.append(str(new.uuids[i]).lower())
        elif st.match[i] >= 0:
            uuids.append(str(old.uuids[st.match[i]]))
        elif restored[i] >= 0:
            assert removed is not None
            uuids.append(str(removed.uuids[restored[i]]))
        else:
            uuids.append(str(uuidlib.uuid4()))
    return uuids


def _assign_by_place(st: _State, news: np.ndarray, olds: np.ndarray, c_new: np.ndarray, c_old: np.ndarray,
                     diagonal: float, tol_same: float, neighbours: int) -> None:
    """Identical parts: min-cost assignment of ``news`` to ``olds`` on aligned centroid distance."""
    old, new = st.old, st.new
    k = min(neighbours, len(olds))
    tree = cKDTree(c_old[olds])
    dist, nn = tree.query(c_new[news], k=k)
    dist, nn = dist.reshape(len(news), k), nn.reshape(len(news), k)
    rows = np.repeat(np.arange(len(news)), k)
    cols = nn.ravel()
    cost = dist.ravel() / diagonal
    if len(news) * len(olds) <= 250_000:  # small: an exact dense assignment over every pair
        full = np.linalg.norm(c_new[news][:, None, :] - c_old[olds][None, :, :], axis=2) / diagonal
        match = dense_assignment(full, unmatched=2.0)
    else:
        match = sparse_assignment(rows, cols, cost, len(news), len(olds), unmatched=2.0)
    old_names: dict[str, int] = {}
    for jj, j in enumerate(olds):
        nm = old.names[j]
        if not is_writer_id(nm):
            old_names[nm] = -1 if nm in old_names else jj  # a name shared by several is no evidence
    chosen = {int(jj): ii for ii, jj in enumerate(match) if jj >= 0}  # old column -> new row (this group)
    c_n, c_o = c_new[news], c_old[olds]
    tie = TIE_RTOL * diagonal + tol_same
    for ii, jj in enumerate(match):
        if jj < 0:
            continue
        i, j = int(news[ii]), int(olds[jj])
        st.bind(i, j, "placement")
        d = float(np.linalg.norm(c_n[ii] - c_o[jj]))
        rivals = []  # other old parts this one could take at no more cost, within the tolerance
        for m in range(k):
            kk = int(nn[ii, m])
            if kk == jj:
                continue
            d_k = float(dist[ii, m])
            other = chosen.get(kk)
            if other is None:  # a free old part: taking it instead costs d_k - d
                delta = d_k - d
            else:  # a swap with the new part that holds it
                delta = (d_k + float(np.linalg.norm(c_n[other] - c_o[jj]))
                         - d - float(np.linalg.norm(c_n[other] - c_o[kk])))
            if delta <= tie:
                rivals.append((d_k, int(olds[kk]), delta))
        if rivals:
            rivals.sort()
            st.ambiguous[i] = {"candidates": [str(old.uuids[j])] + [str(old.uuids[o]) for _, o, _ in rivals[:3]],
                               "reason": f"moved {d:.6g} after the model's alignment, and another identical part "
                                         f"({old.paths[rivals[0][1]]!r}) fits as well (within {tie:.3g})"}
        nm = new.names[i]
        named = old_names.get(nm, -1) if not is_writer_id(nm) else -1
        if named >= 0 and int(olds[named]) != j and old.names[j] != nm:
            st.ambiguous[i] = {"candidates": [str(old.uuids[j]), str(old.uuids[olds[named]])],
                               "reason": f"its placement is that of {old.paths[j]!r} but its name is that of "
                                         f"{old.paths[olds[named]]!r} (identical parts swapped?)"}


def _assemblies_by_votes(st: _State) -> None:
    """Unmatched new assemblies take the old parent most of their matched children had (an assignment)."""
    old, new = st.old, st.new
    votes: dict[tuple[int, int], int] = {}
    size = np.zeros(len(new), np.int64)
    for i in range(len(new)):
        p = new.parent[i]
        if p < 0:
            continue
        size[p] += 1
        if st.match[p] >= 0 or st.rule[p] == "carried" or st.match[i] < 0:
            continue
        op = old.parent[st.match[i]]
        if op >= 0 and not st.taken[op] and not old.leaf[op]:
            votes[(int(p), int(op))] = votes.get((int(p), int(op)), 0) + 1
    if not votes:
        return
    keys = list(votes)
    rows_u, rows = np.unique([a for a, _ in keys], return_inverse=True)
    cols_u, cols = np.unique([b for _, b in keys], return_inverse=True)
    cost = np.array([1.0 - votes[kk] / max(size[kk[0]], 1) for kk in keys])
    match = sparse_assignment(rows, cols, cost, len(rows_u), len(cols_u), unmatched=1.0)
    for r, c in enumerate(match):
        if c >= 0:
            st.bind(int(rows_u[r]), int(cols_u[c]), "structure")


def _reshaped_by_parent(st: _State, diagonal: float) -> None:
    """Unmatched new leaves under a matched parent take an unmatched old leaf of that parent.

    The cost is the distance of their placements in the parent (origins, fraction of the diagonal) plus
    0.5 when product names differ (0.25 when one is a writer's id, which says nothing): a part made
    longer keeps its place and its product name.
    """
    old, new = st.old, st.new
    old_children: dict[int, list[int]] = {}
    for j in np.flatnonzero(~st.taken & old.leaf):
        if old.parent[j] >= 0:
            old_children.setdefault(int(old.parent[j]), []).append(int(j))
    by_parent: dict[int, list[int]] = {}
    for i in np.flatnonzero((st.match < 0) & new.leaf):
        p = new.parent[i]
        if p >= 0 and st.match[p] >= 0 and st.rule[i] != "carried":
            by_parent.setdefault(int(st.match[p]), []).append(int(i))
    for op, news in by_parent.items():
        olds = [j for j in old_children.get(op, []) if not st.taken[j]]
        if not olds:
            continue
        cost = np.zeros((len(news), len(olds)))
        for a, i in enumerate(news):
            for b, j in enumerate(olds):
                d = float(np.linalg.norm(new.local[i, :3, 3] - old.local[j, :3, 3])) / diagonal
                cost[a, b] = d + _name_penalty(new.products[i] or new.names[i], old.products[j] or old.names[j])
        match = dense_assignment(cost, unmatched=0.3)
        for a, b in enumerate(match):
            if b >= 0:
                st.bind(news[a], olds[b], "structure")


def _name_penalty(a: str, b: str) -> float:
    if is_writer_id(a) or is_writer_id(b):
        return 0.25
    return 0.0 if a == b else 0.5


def _restore(st: _State, removed: Side, c_new: np.ndarray, align: np.ndarray, tol: float,
             diagonal: float) -> np.ndarray:
    """New nodes matched to nothing that come back where a removed node was: ``out[i]`` = removed row or -1.

    Leaves: per shape class (faceless leaves: per product name), an optimal assignment on the distance between
    the new centroid and the removed one carried by ``align``; only pairs within ``tol``. Ties within the
    tolerance are reported ambiguous. Assemblies (deepest first): the removed assembly most of whose rows the
    new one's restored children were, if it has the same product or name, or sits where it was.
    """
    new = st.new
    out = np.full(len(new), -1, np.int64)
    free = np.array([st.match[i] < 0 and st.rule[i] == "new" for i in range(len(new))], bool)
    if not free.any():
        return out
    taken = np.zeros(len(removed), bool)
    c_rem = apply_rigid(align, world_centroids(removed))
    nr = len(removed)
    cls = shape_classes(list(removed.keys) + list(new.keys))
    labels: dict[tuple, list[list[int]]] = {}
    for side, base, mask in ((0, 0, removed.leaf), (1, nr, new.leaf & free)):
        s = removed if side == 0 else new
        for i in np.flatnonzero(mask):
            c = cls[base + i]
            key: tuple = ("part", int(c)) if c >= 0 else ("empty", s.products[i] or s.names[i])
            labels.setdefault(key, [[], []])[side].append(int(i))
    tie = TIE_RTOL * diagonal + tol * 1e-3
    for rems, news in labels.values():
        if not rems or not news:
            continue
        d = np.linalg.norm(c_new[news][:, None, :] - c_rem[rems][None, :, :], axis=2)
        match = dense_assignment(np.where(d <= tol, d, 1e9), unmatched=tol + 1.0)
        for a, b in enumerate(match):
            if b < 0 or d[a, b] > tol:
                continue
            i, j = news[a], rems[b]
            out[i] = j
            taken[j] = True
            st.rule[i] = "restored"
            rivals = [rems[m] for m in range(len(rems)) if m != b and d[a, m] <= d[a, b] + tie]
            if rivals:
                st.ambiguous[i] = {"candidates": [str(removed.uuids[j])] + [str(removed.uuids[r]) for r in rivals[:3]],
                                   "reason": f"comes back where two removed identical parts were (within {tie:.3g})"}
    for i in range(len(new) - 1, -1, -1):  # children before parents
        if not free[i] or new.leaf[i] or out[i] >= 0:
            continue
        votes: dict[int, int] = {}
        kids = np.flatnonzero(new.parent == i)
        for ch in kids:
            if out[ch] >= 0 and removed.parent[out[ch]] >= 0:
                p = int(removed.parent[out[ch]])
                votes[p] = votes.get(p, 0) + 1
        if not votes:
            continue
        j, n_votes = max(votes.items(), key=lambda kv: kv[1])
        if taken[j] or removed.leaf[j] or 2 * n_votes < sum(1 for ch in kids if out[ch] >= 0):
            continue
        same_name = (new.products[i] or new.names[i]) == (removed.products[j] or removed.names[j])
        where = np.linalg.norm((align @ removed.world[j])[:3, 3] - new.world[i, :3, 3]) <= tol
        if same_name or where:
            out[i] = j
            taken[j] = True
            st.rule[i] = "restored"
    return out
