"""Pure tree logic: validate a pushed CAD tree, diff two trees by UUID, apply a diff.

Nothing here touches HTTP or the database. Three steps:

- `Tree.build(...)` validates a flat node list with parent links (unique UUIDs, parents
  present, no cycles, finite affine invertible transforms) and computes every node's
  ``world_from_node`` in metres — vectorized, level by level, so 100k nodes cost milliseconds.
- `diff_trees(a, b)` names every UUID added, removed, moved (world transform changed, also
  through a moved ancestor or a changed length unit), geometry_changed, renamed, reparented,
  recolored, and counts the unchanged; it carries the new records (`upserts`) so that
  `apply_diff(a, diff_trees(a, b)) == b`. Node order is not part of a tree: a permutation of
  the node list is no change.
- `apply_to_scene(scene, instances, new_tree, diff, ensure_geometry)` turns a diff into the
  minimal `tracer.Scene` calls: an added node with geometry adds an instance, a removed one
  removes it, a moved one sets its transform, a changed geometry replaces the instance.

Units: local transforms are in the document's ``length_unit``; a mesh's vertices are in the
document unit too. ``world[i]`` maps node-frame metres to world metres (``S·W·S⁻¹`` with
``S = diag(s, s, s, 1)``, ``s`` metres per unit); an instance's transform maps mesh vertices
(document units) to world metres (``S·W``).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from service.errors import Invalid
from service.paths import occurrence_paths
from service.schemas import LENGTH_UNITS

# A transform is singular when |det A| falls below this fraction of the product of its column
# norms (scale-free: a uniform scale of 1e-6 is fine, a flattened axis is not).
SINGULAR_RATIO = 1e-9
# The bottom row of an affine transform may deviate from (0, 0, 0, 1) by this much (float noise).
AFFINE_TOLERANCE = 1e-9
# No entry of a world placement (metres) may exceed this: a million kilometres, far beyond any luminaire, and
# far inside what float32 meshes and float64 rays can hold.
MAX_WORLD_M = 1e9


class TreeError(Invalid):
    """A pushed tree is invalid (422); ``problems`` names each offending node (uuid and what is wrong)."""

    def __init__(self, message: str, problems: list[dict[str, Any]] | None = None) -> None:
        self.problems = problems or []
        super().__init__(message, problems=self.problems[:100])


def _compose(parent: np.ndarray, local: np.ndarray) -> np.ndarray:
    """Batched ``parent @ local`` for (k,4,4) stacks, summed in a fixed order.

    Written out so that each element is computed by the same sequence of float operations
    whatever the batch size or memory layout: the same chain gives bit-identical worlds, which
    makes "moved" an exact comparison. A product that overflows is left to `_check_world` to refuse.
    """
    with np.errstate(over="ignore", invalid="ignore"):
        out = parent[:, :, 0, None] * local[:, None, 0, :]
        out = out + parent[:, :, 1, None] * local[:, None, 1, :]
        out = out + parent[:, :, 2, None] * local[:, None, 2, :]
        out = out + parent[:, :, 3, None] * local[:, None, 3, :]
    return out


@dataclass(eq=False)
class Tree:
    """A validated CAD tree in columns (document order kept, but not part of its identity).

    Attributes
    ----------
    uuids, parents, names, geometries, colors : lists of length n
    local : (n, 4, 4) float64, row-major ``parent_from_node`` in document units
    world : (n, 4, 4) float64, ``world_from_node`` in metres (translation scaled to metres)
    parent_index : (n,) int64, -1 for roots
    depth : (n,) int64, 0 for roots
    index : dict uuid -> row
    """

    length_unit: str
    uuids: list[str]
    parents: list[str | None]
    names: list[str]
    geometries: list[str | None]
    colors: list[tuple[float, float, float] | None]
    local: np.ndarray
    world: np.ndarray
    parent_index: np.ndarray
    depth: np.ndarray
    index: dict[str, int] = field(repr=False)
    levels: list[np.ndarray] = field(repr=False, default_factory=list)  # rows of each depth, roots first
    world_doc: np.ndarray | None = field(repr=False, default=None)  # world_from_node in document units

    @property
    def scale(self) -> float:
        """Metres per document unit."""
        return LENGTH_UNITS[self.length_unit]

    def __len__(self) -> int:
        return len(self.uuids)

    @classmethod
    def empty(cls, length_unit: str = "m") -> Tree:
        return cls.build([], [], [], np.zeros((0, 16)), [], [], length_unit)

    @classmethod
    def build(
        cls,
        uuids: Sequence[str],
        parents: Sequence[str | None],
        names: Sequence[str],
        transforms: np.ndarray | Sequence[Sequence[float]],
        geometries: Sequence[str | None],
        colors: Sequence[tuple[float, float, float] | None] | None,
        length_unit: str,
        like: Tree | None = None,
    ) -> Tree:
        """Validate a node list and compute world transforms.

        Parameters
        ----------
        transforms : (n, 16) or (n, 4, 4) float, row-major local transforms in `length_unit`
        like : a tree with, possibly, the same uuids and parents in the same order (the previous
            revision): its structure (index, parent links, depths; all validated) is then reused and
            only the transforms are checked, the common case of a push that moves parts.

        Raises
        ------
        TreeError
            Duplicate UUIDs, a missing parent, a cycle, a non-finite, non-affine or singular
            transform, an unknown length unit, or columns of different lengths.
        """
        n = len(uuids)
        if length_unit not in LENGTH_UNITS:
            raise TreeError(f"unknown length_unit {length_unit!r}; known: {sorted(LENGTH_UNITS)}")
        colors = list(colors) if colors is not None else [None] * n
        if not (len(parents) == len(names) == len(geometries) == len(colors) == n):
            raise TreeError("node columns have different lengths")
        local = np.asarray(transforms, dtype=np.float64).reshape(n, 4, 4) if n else np.zeros((0, 4, 4))
        uuids = list(uuids)
        parents = list(parents)
        if like is not None and like.uuids == uuids and like.parents == parents:
            changed = ~(local == like.local).all(axis=(1, 2)) if n else np.zeros(0, dtype=bool)
            rows = np.flatnonzero(changed)
            _check_transforms([uuids[i] for i in rows], local[rows])
            world_doc = _world_doc(local, like.parent_index, like.levels, like.world_doc, changed)
            if not len(rows) and length_unit == like.length_unit:
                world = like.world
            else:
                world = _to_metres(world_doc, length_unit)
                _check_world(uuids, world)
            return cls(length_unit, uuids, parents, list(names), list(geometries), colors, local, world,
                       like.parent_index, like.depth, like.index, like.levels, world_doc)

        index = {u: i for i, u in enumerate(uuids)}
        if len(index) != n:
            seen: set[str] = set()
            dups = sorted({u for u in uuids if u in seen or seen.add(u)})  # type: ignore[func-returns-value]
            raise TreeError(f"duplicate node uuid(s): {', '.join(dups[:10])}",
                            [{"uuid": u, "problem": "duplicate uuid"} for u in dups])

        parent_index = np.fromiter((-1 if p is None else index.get(p, -2) for p in parents), dtype=np.int64,
                                   count=n)
        if n and (parent_index == -2).any():
            bad = np.flatnonzero(parent_index == -2)
            problems = [{"uuid": uuids[i], "problem": f"parent {parents[i]} is not in the tree"} for i in bad]
            raise TreeError(f"{len(bad)} node(s) name a parent that is not in the tree, e.g. "
                            f"{uuids[bad[0]]} -> {parents[bad[0]]}", problems)

        _check_transforms(uuids, local)
        depth = _depths(uuids, parent_index)

        levels: list[np.ndarray] = []
        if n:
            order = np.argsort(depth, kind="stable")
            bounds = np.searchsorted(depth[order], np.arange(int(depth.max()) + 2))
            levels = [order[bounds[d]:bounds[d + 1]] for d in range(int(depth.max()) + 1)]
        world_doc = _world_doc(local, parent_index, levels)
        world = _to_metres(world_doc, length_unit)
        _check_world(uuids, world)
        return cls(length_unit, uuids, parents, list(names), list(geometries), colors, local,
                   world, parent_index, depth, index, levels, world_doc)

    # ---------------------------------------------------------------- queries

    def instance_transform(self, row: int) -> np.ndarray:
        """4×4 ``world_from_mesh``: mesh vertices in document units to world metres."""
        t = self.world[row].copy()
        t[:3, :3] *= self.scale
        return t

    def records(self) -> dict[str, tuple]:
        """uuid -> (parent, name, 16 local numbers, geometry, color): the tree's identity (order-free)."""
        return {u: (self.parents[i], self.names[i], tuple(self.local[i].ravel().tolist()), self.geometries[i],
                    self.colors[i]) for i, u in enumerate(self.uuids)}

    def same_as(self, other: Tree) -> bool:
        """Same unit and same node records, whatever the order."""
        return self.length_unit == other.length_unit and self.records() == other.records()

    def paths(self) -> list[str]:
        """Every node's occurrence path, by the rule of `service.paths` (the CAD adapter's too:
        ``cad_adapter.tree.assign_paths``).

        Names from the root joined by ``/``; a ``/`` inside a name becomes ``∕`` (U+2215); among
        siblings sharing a name (roots are siblings of each other) the first in document order keeps
        the bare name, the next are ``name[2]``, ``name[3]``…. O(n).
        """
        return occurrence_paths(self.uuids, self.parents, self.names)

    def subtree(self, uuid: str) -> list[str]:
        """`uuid` and all its descendants (uuids), in document order."""
        root = self.index[uuid]
        inside = np.zeros(len(self), dtype=bool)
        inside[root] = True
        # descendants: walk levels below the root's depth, marking children of marked rows
        for d in range(int(self.depth[root]) + 1, int(self.depth.max(initial=0)) + 1):
            rows = np.flatnonzero(self.depth == d)
            inside[rows] |= inside[self.parent_index[rows]]
        return [self.uuids[i] for i in np.flatnonzero(inside)]


def _world_doc(local: np.ndarray, parent_index: np.ndarray, levels: list[np.ndarray],
               base: np.ndarray | None = None, dirty: np.ndarray | None = None) -> np.ndarray:
    """world_from_node (document units) of every row, level by level (parents before children).

    With `base` (the previous worlds, same structure) and `dirty` (rows whose local transform
    changed), only the dirty rows and their descendants are recomputed — by the same operations
    as a full pass, so the result is bit-identical to one.
    """
    if base is not None and dirty is not None:
        if not dirty.any():
            return base
        world = base.copy()
        mark = dirty.copy()
        for rows in levels:
            if rows is not levels[0]:
                mark[rows] |= mark[parent_index[rows]]
            sel = rows[mark[rows]]
            if len(sel):
                world[sel] = local[sel] if rows is levels[0] else _compose(world[parent_index[sel]], local[sel])
        return world
    world = np.empty_like(local)
    if not len(local):
        return world
    world[levels[0]] = local[levels[0]]
    for rows in levels[1:]:
        world[rows] = _compose(world[parent_index[rows]], local[rows])
    return world


def _to_metres(world_doc: np.ndarray, length_unit: str) -> np.ndarray:
    """``S·W·S⁻¹``: the same frames with their translations in metres."""
    world = world_doc.copy()
    world[:, :3, 3] *= LENGTH_UNITS[length_unit]
    return world


def _check_transforms(uuids: Sequence[str], local: np.ndarray) -> None:
    if not len(uuids):
        return
    finite = np.isfinite(local).all(axis=(1, 2))
    if not finite.all():
        i = int(np.flatnonzero(~finite)[0])
        raise TreeError(f"node {uuids[i]}: transform has a non-finite number",
                        [{"uuid": uuids[int(j)], "problem": "non-finite transform"} for j in np.flatnonzero(~finite)])
    bottom = np.abs(local[:, 3, :] - np.array([0.0, 0.0, 0.0, 1.0])).max(axis=1)
    bad = bottom > AFFINE_TOLERANCE
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise TreeError(f"node {uuids[i]}: transform is not affine (its last row must be 0 0 0 1, got "
                        f"{local[i, 3].tolist()})",
                        [{"uuid": uuids[int(j)], "problem": "last row is not 0 0 0 1"} for j in np.flatnonzero(bad)])
    a = local[:, :3, :3]
    det = np.linalg.det(a)
    norms = np.linalg.norm(a, axis=1).prod(axis=1)  # product of the column norms
    singular = ~(np.abs(det) > SINGULAR_RATIO * norms)
    if singular.any():
        i = int(np.flatnonzero(singular)[0])
        raise TreeError(f"node {uuids[i]}: transform is singular (det {det[i]:.3g}); a part cannot be flattened",
                        [{"uuid": uuids[int(j)], "problem": "singular transform"} for j in np.flatnonzero(singular)])


def _check_world(uuids: Sequence[str], world: np.ndarray) -> None:
    """Each local transform may be valid and their product not: a world placement must stay finite, within
    `MAX_WORLD_M` and invertible (five ×1e100 scales overflow, five ×1e-100 ones flatten a part)."""
    if not len(uuids):
        return
    with np.errstate(all="ignore"):
        big = np.abs(world).max(axis=(1, 2))
        a = world[:, :3, :3]
        det = np.linalg.det(a)
        norms = np.linalg.norm(a, axis=1).prod(axis=1)
    bad = ~(big <= MAX_WORLD_M) | ~(np.abs(det) > SINGULAR_RATIO * norms)
    if bad.any():
        rows = np.flatnonzero(bad)
        i = int(rows[0])
        what = f"beyond {MAX_WORLD_M:g} m or not finite" if not big[i] <= MAX_WORLD_M else "singular"
        raise TreeError(f"node {uuids[i]}: its world placement (the product of the transforms from the root) is "
                        f"{what}; check the scales and translations of it and its ancestors",
                        [{"uuid": uuids[int(j)], "problem": "world placement out of range"} for j in rows[:100]])


def _depths(uuids: Sequence[str], parent_index: np.ndarray) -> np.ndarray:
    """Depth of every node by pointer doubling (O(n log depth)); raises TreeError on a cycle."""
    n = len(parent_index)
    depth = (parent_index >= 0).astype(np.int64)
    jump = parent_index.copy()
    for _ in range(max(1, int(np.ceil(np.log2(max(n, 2))))) + 1):
        live = jump >= 0
        if not live.any():
            return depth
        target = jump[live]
        depth_new = depth.copy()
        depth_new[live] += depth[target]
        jump_new = jump.copy()
        jump_new[live] = jump[target]
        depth, jump = depth_new, jump_new
    # whatever still has an ancestor pointer after log2(n)+1 doublings never reaches a root
    stuck = np.flatnonzero(jump >= 0)
    cyc = _cycle_members(parent_index, int(stuck[0]))
    raise TreeError(f"the tree has a cycle through node(s) {', '.join(uuids[i] for i in cyc[:10])}",
                    [{"uuid": uuids[i], "problem": "on a parent cycle"} for i in cyc])


def _cycle_members(parent_index: np.ndarray, start: int) -> list[int]:
    seen: dict[int, int] = {}
    i = start
    while i not in seen:
        seen[i] = len(seen)
        i = int(parent_index[i])
    first = seen[i]
    return [k for k, pos in seen.items() if pos >= first]


# ---------------------------------------------------------------- diff

@dataclass
class TreeDiff:
    """What changed from tree `a` to tree `b`, by UUID (lists in `b`'s order; `removed` in `a`'s).

    ``upserts`` holds `b`'s record for every added node and every node whose own record changed,
    so that `apply_diff` can rebuild `b` from `a`.
    """

    added: list[str]
    removed: list[str]
    moved: list[str]
    geometry_changed: list[str]
    renamed: list[str]
    reparented: list[str]
    recolored: list[str]
    unchanged: int
    length_unit: str
    length_unit_changed: bool
    upserts: dict[str, tuple] = field(repr=False)

    def is_empty(self) -> bool:
        return not (self.added or self.removed or self.moved or self.geometry_changed or self.renamed
                    or self.reparented or self.recolored or self.upserts or self.length_unit_changed)

    def summary(self) -> dict[str, Any]:
        return {"added": self.added, "removed": self.removed, "moved": self.moved,
                "geometry_changed": self.geometry_changed, "renamed": self.renamed, "reparented": self.reparented,
                "recolored": self.recolored, "unchanged": self.unchanged}


def diff_trees(a: Tree, b: Tree) -> TreeDiff:
    """Diff two validated trees by UUID: one linear pass, vectorized where it counts."""
    if a is b:
        return TreeDiff([], [], [], [], [], [], [], len(a), a.length_unit, False, {})
    if a.uuids == b.uuids:
        return _diff_same_order(a, b)
    return _diff_general(a, b)


def _diff_same_order(a: Tree, b: Tree) -> TreeDiff:
    """The common case — same nodes in the same order — with whole-column comparisons."""
    n = len(b)
    uu = b.uuids
    moved_mask = ~(a.world == b.world).all(axis=(1, 2)) if n else np.zeros(0, dtype=bool)
    changed = ~(a.local == b.local).all(axis=(1, 2)) if n else np.zeros(0, dtype=bool)
    any_change = moved_mask.copy()

    def column(xa: list, xb: list) -> list[int]:
        if xa == xb:
            return []
        return [k for k in range(n) if xa[k] != xb[k]]

    geometry = column(a.geometries, b.geometries)
    names = column(a.names, b.names)
    parents = column(a.parents, b.parents)
    colors = column(a.colors, b.colors)
    for rows in (geometry, names, parents, colors):
        if rows:
            changed[rows] = True
            any_change[rows] = True
    upserts = {uu[k]: _record(b, int(k)) for k in np.flatnonzero(changed)}
    return TreeDiff([], [], [uu[k] for k in np.flatnonzero(moved_mask)], [uu[k] for k in geometry],
                    [uu[k] for k in names], [uu[k] for k in parents], [uu[k] for k in colors],
                    int(n - any_change.sum()), b.length_unit, a.length_unit != b.length_unit, upserts)


def _diff_general(a: Tree, b: Tree) -> TreeDiff:
    """Any two trees: match rows by uuid, then compare."""
    index_a = a.index
    rows_b_common: list[int] = []
    rows_a_common: list[int] = []
    added: list[str] = []
    for j, u in enumerate(b.uuids):
        i = index_a.get(u)
        if i is None:
            added.append(u)
        else:
            rows_a_common.append(i)
            rows_b_common.append(j)
    index_b = b.index
    removed = [u for u in a.uuids if u not in index_b] if len(rows_a_common) != len(a) else []

    ia = np.asarray(rows_a_common, dtype=np.int64)
    ib = np.asarray(rows_b_common, dtype=np.int64)
    if len(ia):
        world_same = (a.world[ia] == b.world[ib]).all(axis=(1, 2))
        local_same = (a.local[ia] == b.local[ib]).all(axis=(1, 2))
    else:
        world_same = local_same = np.zeros(0, dtype=bool)
    moved_mask = ~world_same

    moved: list[str] = []
    geometry_changed: list[str] = []
    renamed: list[str] = []
    reparented: list[str] = []
    recolored: list[str] = []
    changed_rows: list[int] = []
    unchanged = 0
    ag, bg, an, bn, ap, bp, ac, bc = a.geometries, b.geometries, a.names, b.names, a.parents, b.parents, \
        a.colors, b.colors
    for k in range(len(ib)):
        i = rows_a_common[k]
        j = rows_b_common[k]
        any_change = False
        record_changed = not local_same[k]
        if moved_mask[k]:
            moved.append(b.uuids[j])
            any_change = True
        if ag[i] != bg[j]:
            geometry_changed.append(b.uuids[j])
            any_change = record_changed = True
        if an[i] != bn[j]:
            renamed.append(b.uuids[j])
            any_change = record_changed = True
        if ap[i] != bp[j]:
            reparented.append(b.uuids[j])
            any_change = record_changed = True
        if ac[i] != bc[j]:
            recolored.append(b.uuids[j])
            any_change = record_changed = True
        if record_changed:
            changed_rows.append(j)
        if not any_change:
            unchanged += 1
    upserts = {b.uuids[j]: _record(b, j) for j in changed_rows}
    for u in added:
        upserts[u] = _record(b, index_b[u])
    return TreeDiff(added, removed, moved, geometry_changed, renamed, reparented, recolored, unchanged,
                    b.length_unit, a.length_unit != b.length_unit, upserts)


def _record(t: Tree, row: int) -> tuple:
    return (t.parents[row], t.names[row], tuple(t.local[row].ravel().tolist()), t.geometries[row], t.colors[row])


def apply_diff(a: Tree, diff: TreeDiff) -> Tree:
    """The tree `b` that `diff` was computed against (`a`'s order, added nodes appended)."""
    removed = set(diff.removed)
    uuids: list[str] = []
    recs: list[tuple] = []
    for i, u in enumerate(a.uuids):
        if u in removed:
            continue
        uuids.append(u)
        recs.append(diff.upserts.get(u) or _record(a, i))
    for u, rec in diff.upserts.items():
        if u not in a.index:
            uuids.append(u)
            recs.append(rec)
    return Tree.build(uuids, [r[0] for r in recs], [r[1] for r in recs],
                      np.array([r[2] for r in recs], dtype=np.float64).reshape(-1, 16),
                      [r[3] for r in recs], [r[4] for r in recs], diff.length_unit)


# ---------------------------------------------------------------- scene application

class SceneLike(Protocol):
    """The part of `tracer.Scene` the apply step uses (docs/DESIGN.md API)."""

    def add_instance(self, gid: str, transform: np.ndarray) -> int: ...
    def set_transform(self, instance: int, transform: np.ndarray) -> None: ...
    def remove_instance(self, instance: int) -> None: ...


@dataclass
class ApplyStats:
    """What `apply_to_scene` did to the scene (before commit)."""

    instances_added: int = 0
    instances_removed: int = 0
    instances_moved: int = 0
    new_geometries: list[str] = field(default_factory=list)  # ids `ensure_geometry` had to add
    reused_geometries: list[str] = field(default_factory=list)  # ids of added instances already in the scene


def apply_to_scene(
    scene: SceneLike,
    instances: dict[str, int],
    new: Tree,
    diff: TreeDiff,
    ensure_geometry: Callable[[str], bool],
) -> ApplyStats:
    """Apply `diff` (computed against `new`) to `scene`, updating `instances` (uuid -> instance id) in place.

    ``ensure_geometry(gid)`` makes the mesh known to the scene and returns True when it had to
    add it (its bottom level will be built or loaded at commit). Top-level work only for moves,
    removals and added copies of known geometry. The caller commits.
    """
    stats = ApplyStats()
    for u in diff.removed:
        inst = instances.pop(u, None)
        if inst is not None:
            scene.remove_instance(inst)
            stats.instances_removed += 1
    changed_geometry = set(diff.geometry_changed)
    for u in diff.geometry_changed:
        inst = instances.pop(u, None)
        if inst is not None:
            scene.remove_instance(inst)
            stats.instances_removed += 1
    seen_new: set[str] = set()
    for u in list(diff.added) + diff.geometry_changed:
        row = new.index[u]
        gid = new.geometries[row]
        if gid is None:
            continue
        if ensure_geometry(gid):
            seen_new.add(gid)
        elif gid not in seen_new:
            stats.reused_geometries.append(gid)
            seen_new.add(gid)
        instances[u] = scene.add_instance(gid, new.instance_transform(row))
        stats.instances_added += 1
    stats.new_geometries = sorted(g for g in seen_new if g not in stats.reused_geometries)
    # a changed length unit rescales every mesh (instance = S·W) even where the node frame stays put
    to_move = [u for u in new.uuids if u in instances] if diff.length_unit_changed else diff.moved
    just_added = set(diff.added)
    for u in to_move:
        if u in changed_geometry or u in just_added:
            continue
        inst = instances.get(u)
        if inst is not None:
            scene.set_transform(inst, new.instance_transform(new.index[u]))
            stats.instances_moved += 1
    return stats


def nodes_to_columns(nodes: Iterable[Any]) -> tuple[list, list, list, np.ndarray, list, list]:
    """Columns (uuids, parents, names, transforms (n,16), geometries, colors) from parsed `NodeIn` models."""
    nodes = list(nodes)
    uuids = [x.uuid for x in nodes]
    parents = [x.parent for x in nodes]
    names = [x.name for x in nodes]
    geometries = [x.geometry for x in nodes]
    colors = [tuple(x.color) if x.color is not None else None for x in nodes]
    transforms = np.array([x.transform for x in nodes], dtype=np.float64).reshape(len(nodes), 16)
    return uuids, parents, names, transforms, geometries, colors
