"""The pure diff module (service.tree): validation, world transforms, diff, apply — no HTTP, no database.

Property tests draw random trees over a shared pool of UUIDs (so two draws overlap), with
transforms built from 90° rotations, integer translations and power-of-two scales: their
products are exact in float64, so "moved" can be checked against a brute-force recursive
product without tolerance questions.
"""

from __future__ import annotations

import itertools
import uuid as uuidlib

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from service_fakes import FakeScene

from service.schemas import LENGTH_UNITS
from service.tree import Tree, TreeError, apply_diff, apply_to_scene, diff_trees

POOL = [str(uuidlib.UUID(int=i + 1)) for i in range(24)]
GEOMS = ["a" * 64, "b" * 64, "c" * 64]
NAMES = ["body", "door", "wheel"]
COLORS = [None, (0.5, 0.5, 0.5), (1.0, 0.0, 0.0)]


def rot(axis: int, quarter: int) -> np.ndarray:
    c, s = [(1, 0), (0, 1), (-1, 0), (0, -1)][quarter % 4]
    m = np.eye(4)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


@st.composite
def transforms(draw) -> list[float]:
    m = rot(draw(st.integers(0, 2)), draw(st.integers(0, 3)))
    m[:3, :3] *= draw(st.sampled_from([1.0, 2.0, 0.5]))
    m[:3, 3] = [draw(st.integers(-3, 3)) for _ in range(3)]
    return m.ravel().tolist()


@st.composite
def trees(draw, min_size: int = 0) -> Tree:
    """A random valid tree: each node's parent is an earlier node (so no cycles), then shuffled."""
    uuids = draw(st.lists(st.sampled_from(POOL), min_size=min_size, max_size=14, unique=True))
    parents: list[str | None] = []
    for k in range(len(uuids)):
        p = draw(st.integers(-1, k - 1))
        parents.append(None if p < 0 else uuids[p])
    rows = [(u, parents[k], draw(st.sampled_from(NAMES)), draw(transforms()),
             draw(st.sampled_from([None, *GEOMS])), draw(st.sampled_from(COLORS))) for k, u in enumerate(uuids)]
    rows = draw(st.permutations(rows))
    unit = draw(st.sampled_from(["m", "mm"]))
    return build(rows, unit)


def build(rows, unit: str = "m") -> Tree:
    return Tree.build([r[0] for r in rows], [r[1] for r in rows], [r[2] for r in rows],
                      np.array([r[3] for r in rows], dtype=float).reshape(-1, 16), [r[4] for r in rows],
                      [r[5] for r in rows], unit)


def rows_of(t: Tree) -> list[tuple]:
    return [(u, t.parents[i], t.names[i], t.local[i].ravel().tolist(), t.geometries[i], t.colors[i])
            for i, u in enumerate(t.uuids)]


def brute_world(t: Tree, u: str) -> np.ndarray:
    """world_from_node in metres by the definition: product of local transforms up the chain."""
    i = t.index[u]
    m = t.local[i].copy()
    p = t.parents[i]
    while p is not None:
        m = t.local[t.index[p]] @ m
        p = t.parents[t.index[p]]
    m[:3, 3] *= LENGTH_UNITS[t.length_unit]
    return m


def scene_state(scene: FakeScene, instances: dict[str, int]) -> dict[str, tuple[str, list]]:
    return {u: (scene.inst[i][0], scene.inst[i][1].round(12).tolist()) for u, i in instances.items()}


def fresh(t: Tree) -> tuple[FakeScene, dict[str, int]]:
    scene = FakeScene()
    instances: dict[str, int] = {}
    apply_to_scene(scene, instances, t, diff_trees(Tree.empty(t.length_unit), t), lambda g: _known(scene, g))
    return scene, instances


def _known(scene: FakeScene, gid: str) -> bool:
    new = gid not in scene.geoms
    scene.known(gid)
    return new


EXAMPLES = settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])


# ---------------------------------------------------------------- properties


@EXAMPLES
@given(trees(), trees())
def test_diff_applied_to_a_gives_b(a: Tree, b: Tree) -> None:
    d = diff_trees(a, b)
    assert apply_diff(a, d).same_as(b)


@EXAMPLES
@given(trees(), st.randoms(use_true_random=False))
def test_permutation_of_the_node_list_is_no_change(a: Tree, rnd) -> None:
    rows = rows_of(a)
    rnd.shuffle(rows)
    b = build(rows, a.length_unit)
    d = diff_trees(a, b)
    assert d.is_empty()
    assert d.unchanged == len(a)


@EXAMPLES
@given(trees())
def test_diff_with_itself_is_empty(a: Tree) -> None:
    d = diff_trees(a, a)
    assert d.is_empty() and d.unchanged == len(a) and not d.upserts


@EXAMPLES
@given(trees())
def test_world_transforms_match_the_recursive_definition(a: Tree) -> None:
    for u in a.uuids:
        np.testing.assert_array_equal(a.world[a.index[u]], brute_world(a, u))


@EXAMPLES
@given(trees(), trees())
def test_diff_categories_are_exact(a: Tree, b: Tree) -> None:
    d = diff_trees(a, b)
    sa, sb = set(a.uuids), set(b.uuids)
    assert set(d.added) == sb - sa and len(d.added) == len(sb - sa)
    assert set(d.removed) == sa - sb and len(d.removed) == len(sa - sb)
    common = sa & sb
    moved = {u for u in common if not np.array_equal(brute_world(a, u), brute_world(b, u))}
    assert set(d.moved) == moved
    assert set(d.geometry_changed) == {u for u in common if a.geometries[a.index[u]] != b.geometries[b.index[u]]}
    assert set(d.renamed) == {u for u in common if a.names[a.index[u]] != b.names[b.index[u]]}
    assert set(d.reparented) == {u for u in common if a.parents[a.index[u]] != b.parents[b.index[u]]}
    changed = set(d.moved) | set(d.geometry_changed) | set(d.renamed) | set(d.reparented) | set(d.recolored)
    assert d.unchanged == len(common - changed)


@EXAMPLES
@given(trees(), trees())
def test_apply_to_scene_equals_a_fresh_build_and_touches_only_the_diff(a: Tree, b: Tree) -> None:
    scene, instances = fresh(a)
    before = dict(scene.calls)
    d = diff_trees(a, b)
    stats = apply_to_scene(scene, instances, b, d, lambda g: _known(scene, g))
    ref_scene, ref_instances = fresh(b)
    assert scene_state(scene, instances) == scene_state(ref_scene, ref_instances)
    assert set(scene.inst) == set(instances.values())  # no stray instances
    ops = {k: scene.calls[k] - before[k] for k in scene.calls}
    assert ops["remove_instance"] <= len(d.removed) + len(d.geometry_changed)
    assert ops["add_instance"] <= len(d.added) + len(d.geometry_changed)
    assert ops["set_transform"] <= (len(instances) if d.length_unit_changed else len(d.moved))
    assert stats.instances_added == ops["add_instance"] and stats.instances_removed == ops["remove_instance"]


@EXAMPLES
@given(trees(min_size=1), st.data())
def test_moving_a_node_moves_exactly_its_subtree(a: Tree, data) -> None:
    u = data.draw(st.sampled_from(a.uuids))
    rows = rows_of(a)
    k = next(i for i, r in enumerate(rows) if r[0] == u)
    m = np.array(rows[k][3]).reshape(4, 4)
    m[:3, 3] += [1.0, 0.0, 0.0]
    rows[k] = (*rows[k][:3], m.ravel().tolist(), *rows[k][4:])
    b = build(rows, a.length_unit)
    d = diff_trees(a, b)
    assert set(d.moved) == set(a.subtree(u))
    assert not d.added and not d.removed and not d.geometry_changed and not d.renamed
    assert list(d.upserts) == [u]  # only the moved node's own record changed


@EXAMPLES
@given(trees(min_size=1))
def test_a_length_unit_change_moves_every_node_off_the_origin_or_scaled(a: Tree) -> None:
    other = "mm" if a.length_unit == "m" else "m"
    b = build(rows_of(a), other)
    d = diff_trees(a, b)
    assert d.length_unit_changed and not d.is_empty()
    assert apply_diff(a, d).same_as(b)
    expect = {u for u in a.uuids if not np.array_equal(brute_world(a, u), brute_world(b, u))}
    assert set(d.moved) == expect
    # every mesh is rescaled, moved or not: the scene equals a fresh build of b
    scene, instances = fresh(a)
    apply_to_scene(scene, instances, b, d, lambda g: _known(scene, g))
    ref_scene, ref_instances = fresh(b)
    assert scene_state(scene, instances) == scene_state(ref_scene, ref_instances)


# ---------------------------------------------------------------- examples


def chain(n: int, unit: str = "m") -> list[tuple]:
    t = np.eye(4)
    t[0, 3] = 1.0
    return [(POOL[i], POOL[i - 1] if i else None, f"n{i}", t.ravel().tolist(), GEOMS[0], None) for i in range(n)]


def test_world_of_a_chain_in_millimetres() -> None:
    tree = build(chain(5), "mm")
    # node k sits k+1 mm along x: world translation in metres
    assert tree.world[:, 0, 3].tolist() == pytest.approx([0.001 * (k + 1) for k in range(5)])
    # an instance maps mesh vertices (mm) to metres: linear part scaled by 1e-3
    np.testing.assert_allclose(tree.instance_transform(0)[:3, :3], np.eye(3) * 1e-3)


def test_moving_the_root_moves_every_descendant() -> None:
    rows = chain(6)
    a = build(rows)
    t = np.eye(4)
    t[2, 3] = 5.0
    rows[0] = (*rows[0][:3], t.ravel().tolist(), *rows[0][4:])
    d = diff_trees(a, build(rows))
    assert d.moved == POOL[:6] and list(d.upserts) == [POOL[0]] and d.unchanged == 0


def test_reparent_with_the_same_world_is_not_a_move() -> None:
    ident = np.eye(4).ravel().tolist()
    a = build([(POOL[0], None, "r", ident, None, None), (POOL[1], None, "s", ident, None, None),
               (POOL[2], POOL[0], "c", ident, GEOMS[0], None)])
    b = build([(POOL[0], None, "r", ident, None, None), (POOL[1], None, "s", ident, None, None),
               (POOL[2], POOL[1], "c", ident, GEOMS[0], None)])
    d = diff_trees(a, b)
    assert d.reparented == [POOL[2]] and d.moved == [] and d.unchanged == 2


def test_geometry_change_replaces_one_instance_and_reuses_known_geometry() -> None:
    rows = chain(3)
    a = build(rows)
    scene, instances = fresh(a)
    rows[1] = (*rows[1][:4], GEOMS[1], None)
    rows.append((POOL[9], None, "copy", np.eye(4).ravel().tolist(), GEOMS[0], None))
    b = build(rows)
    d = diff_trees(a, b)
    assert d.geometry_changed == [POOL[1]] and d.added == [POOL[9]]
    calls = dict(scene.calls)
    stats = apply_to_scene(scene, instances, b, d, lambda g: _known(scene, g))
    assert scene.calls["remove_instance"] - calls["remove_instance"] == 1
    assert scene.calls["add_instance"] - calls["add_instance"] == 2
    assert stats.new_geometries == [GEOMS[1]] and stats.reused_geometries == [GEOMS[0]]


@pytest.mark.parametrize("n", [1000, 20000])
def test_large_flat_tree_move_one_part(n: int) -> None:
    ident = np.eye(4)
    rows = [(str(uuidlib.UUID(int=10**6 + i)), None if i == 0 else str(uuidlib.UUID(int=10**6)), f"p{i}",
             ident.ravel().tolist(), GEOMS[i % 3] if i else None, None) for i in range(n)]
    a = build(rows)
    moved = ident.copy()
    moved[1, 3] = 0.25
    rows[n // 2] = (*rows[n // 2][:3], moved.ravel().tolist(), *rows[n // 2][4:])
    d = diff_trees(a, build(rows))
    assert d.moved == [rows[n // 2][0]] and d.unchanged == n - 1


# ---------------------------------------------------------------- invalid trees


def ident() -> list[float]:
    return np.eye(4).ravel().tolist()


def test_duplicate_uuids_are_named() -> None:
    with pytest.raises(TreeError, match="duplicate") as exc:
        build([(POOL[0], None, "a", ident(), None, None), (POOL[0], None, "b", ident(), None, None)])
    assert exc.value.problems == [{"uuid": POOL[0], "problem": "duplicate uuid"}]


def test_missing_parent_is_named() -> None:
    with pytest.raises(TreeError, match="parent") as exc:
        build([(POOL[0], POOL[5], "a", ident(), None, None)])
    assert exc.value.problems[0]["uuid"] == POOL[0]


@pytest.mark.parametrize("length", [1, 2, 3, 17])
def test_cycles_are_found_and_named(length: int) -> None:
    rows = [(POOL[i], POOL[(i + 1) % length], f"n{i}", ident(), None, None) for i in range(length)]
    rows += [(POOL[20], None, "root", ident(), None, None), (POOL[21], POOL[0], "hanger", ident(), None, None)]
    with pytest.raises(TreeError, match="cycle") as exc:
        build(rows)
    assert {p["uuid"] for p in exc.value.problems} == set(POOL[:length])


def test_a_long_chain_is_not_a_cycle() -> None:
    tree = build(chain(len(POOL)))
    assert tree.depth.max() == len(POOL) - 1


@pytest.mark.parametrize("bad, match", [
    (np.diag([1.0, 1.0, 0.0, 1.0]), "singular"),
    (np.array([[1.0, 2.0, 0, 0], [2.0, 4.0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]), "singular"),
    (np.diag([1.0, 1.0, 1.0, 2.0]), "affine"),
    (np.array([[1.0, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0.5, 0, 0, 1]]), "affine"),
    (np.diag([np.nan, 1.0, 1.0, 1.0]), "non-finite"),
    (np.diag([np.inf, 1.0, 1.0, 1.0]), "non-finite"),
])
def test_bad_transforms_are_refused(bad: np.ndarray, match: str) -> None:
    with pytest.raises(TreeError, match=match):
        build([(POOL[0], None, "a", ident(), None, None), (POOL[1], POOL[0], "b", bad.ravel().tolist(), None, None)])


@pytest.mark.parametrize("scale", [1e-6, 1e6])
def test_uniform_scales_are_not_singular(scale: float) -> None:
    m = np.diag([scale, scale, scale, 1.0])
    assert len(build([(POOL[0], None, "a", m.ravel().tolist(), None, None)])) == 1


def test_unknown_length_unit() -> None:
    with pytest.raises(TreeError, match="length_unit"):
        build([], "furlong")


def test_empty_trees() -> None:
    e = Tree.empty()
    assert diff_trees(e, e).is_empty()
    a = build(chain(3))
    d = diff_trees(a, e)
    assert d.removed == POOL[:3] and apply_diff(a, d).same_as(e)


def test_every_pair_of_small_examples_round_trips() -> None:
    """Exhaustive over a few hand-made trees: every ordered pair satisfies diff/apply."""
    ident_rows = [(POOL[i], None, "x", ident(), GEOMS[i % 3], None) for i in range(3)]
    examples = [[], chain(3), chain(4, "mm"), ident_rows, chain(2) + ident_rows[2:]]
    for ra, rb in itertools.product(examples, repeat=2):
        a, b = build(ra), build(rb)
        assert apply_diff(a, diff_trees(a, b)).same_as(b)


@st.composite
def edited(draw, a: Tree) -> Tree:
    """`a` with some records edited in place (same uuids, same order): the push-that-moves-parts case."""
    rows = rows_of(a)
    for k in range(len(rows)):
        if draw(st.booleans()):
            u, p, name, t, g, c = rows[k]
            what = draw(st.sampled_from(["move", "rename", "geometry", "color"]))
            if what == "move":
                t = draw(transforms())
            elif what == "rename":
                name = draw(st.sampled_from(NAMES))
            elif what == "geometry":
                g = draw(st.sampled_from([None, *GEOMS]))
            else:
                c = draw(st.sampled_from(COLORS))
            rows[k] = (u, p, name, t, g, c)
    return build(rows, draw(st.sampled_from([a.length_unit, "mm"])))


@EXAMPLES
@given(st.data())
def test_same_order_fast_paths_agree_with_the_general_ones(data) -> None:
    from service.tree import _diff_general, _diff_same_order

    a = data.draw(trees())
    b = data.draw(edited(a))
    fast, slow = _diff_same_order(a, b), _diff_general(a, b)
    assert fast.summary() == slow.summary() and fast.upserts == slow.upserts
    assert fast.length_unit_changed == slow.length_unit_changed
    rows = rows_of(b)
    reused = Tree.build([r[0] for r in rows], [r[1] for r in rows], [r[2] for r in rows],
                        np.array([r[3] for r in rows]).reshape(-1, 16), [r[4] for r in rows], [r[5] for r in rows],
                        b.length_unit, like=a)
    np.testing.assert_array_equal(reused.world, b.world)
    assert reused.same_as(b)


def test_like_is_ignored_when_the_structure_differs() -> None:
    a = build(chain(4))
    rows = chain(4)
    rows[3] = (rows[3][0], POOL[0], *rows[3][2:])  # reparent the last node to the root
    b = Tree.build([r[0] for r in rows], [r[1] for r in rows], [r[2] for r in rows],
                   np.array([r[3] for r in rows]).reshape(-1, 16), [r[4] for r in rows], [r[5] for r in rows], "m",
                   like=a)
    assert b.world[3, 0, 3] == 2.0 and b.depth.tolist() == [0, 1, 2, 1]
