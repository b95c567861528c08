"""Identity against the scene's tree: global matching, alignment of moved models, tolerant change detection.

The "scene" here is the record list the service answers to ``GET /scenes/{id}/nodes``
(``cad_adapter.identity.node_records`` of the previous reading). Each test checks identity the way a
user would: by where the part is in the world, not by which rule fired.
"""

from __future__ import annotations

import math

import cadquery as cq
import numpy as np
import pytest
from cad_helpers import AS1, STAMP, needs_fixtures

from cad_adapter.alignment import kabsch, robust_alignment, sparse_assignment
from cad_adapter.assembly import read_assembly
from cad_adapter.identity import identify, node_records, shape_signature
from cad_adapter.sides import display_name, is_writer_id
from cad_adapter.step_reader import read_step

BOARD = cq.Workplane().box(80, 50, 1.6)
LED = cq.Workplane().box(3, 3, 1.2).faces(">Z").fillet(0.4)
CHIP = cq.Workplane().box(10, 10, 1.5)
JACK = cq.Workplane().box(8, 6, 4)
WASHER = cq.Workplane().circle(4).circle(2).extrude(0.8)


def rz(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def loc_of(m: np.ndarray) -> cq.Location:
    """A cadquery Location from a 4×4 rigid matrix."""
    from OCP.gp import gp_Trsf

    t = gp_Trsf()
    t.SetValues(*[float(m[r, c]) for r in range(3) for c in range(4)])
    return cq.Location(t)


def board(whole: np.ndarray | None = None, names: list[str] | None = None, drop: int | None = None,
          washers: int = 0, board_shape=BOARD) -> cq.Assembly:
    """A circuit board: substrate, chip and jack (unique) and 12 identical LEDs (and washers) in a grid.

    ``whole`` moves the whole model, baked into every child's placement as writers do; ``names`` renames
    the LEDs in order; ``drop`` leaves one LED out.
    """
    whole = np.eye(4) if whole is None else whole
    root = cq.Assembly(name="pcb")

    def add(obj, name, xyz):
        m = np.eye(4)
        m[:3, 3] = xyz
        root.add(obj, name=name, loc=loc_of(whole @ m))

    add(board_shape, "substrate", (0, 0, 0))
    add(CHIP, "U1", (-20, 10, 1.55))
    add(JACK, "J1", (33, -18, 2.8))
    k = 0
    for row in range(3):
        for col in range(4):
            if k != drop:
                add(LED, (names or [f"D{i + 1}" for i in range(12)])[k], (-24 + 16 * col, -12 + 12 * row, 1.4))
            k += 1
    for w in range(washers):
        add(WASHER, f"washer_{w + 1}", (-36 + 10 * w, 22, -1.2))
    return root


def records(doc) -> list[dict]:
    return node_records(doc, {k: f"{i:064x}" for i, k in enumerate(doc.parts)})


def world_of(doc) -> dict[str, np.ndarray]:
    """uuid -> world centroid of the node's part (rounded to 1e-6)."""
    out = {}
    for n in doc.nodes:
        if n.part is not None:
            c = np.append(shape_signature(doc.parts[n.part].shape)["centroid"], 1.0)
            out[n.uuid] = np.round((doc.world_transform(n.index) @ c)[:3], 6)
    return out


def first(assy) -> tuple:
    doc = read_assembly(assy)
    identify(doc, None)
    return doc, records(doc)


def test_whole_board_turned_90_keeps_each_leds_own_uuid() -> None:
    a, scene = first(board())
    turn = rz(90.0)
    turn[:3, 3] = (120.0, -40.0, 5.0)
    b = read_assembly(board(whole=turn, names=[f"NAUO{30 + 7 * i}" for i in range(12)]))  # ids renumbered
    counts = identify(b, None, previous=scene)
    assert counts["new"] == 0 and not b.reconciliation["ambiguous"]
    wa, wb = world_of(a), world_of(b)
    for u, p in wb.items():
        assert u in wa, "a node lost its UUID"
        np.testing.assert_allclose(p, np.round((turn @ np.append(wa[u], 1.0))[:3], 6), atol=1e-5)
    assert b.reconciliation_detail["alignment_inliers"] >= 3
    np.testing.assert_allclose(np.array(b.reconciliation_detail["alignment"]), turn, atol=1e-9)


def test_substrate_turned_inside_its_own_frame_keeps_its_uuid() -> None:
    a, scene = first(board())
    turned = cq.Workplane().box(50, 80, 1.6)  # the same solid, its frame turned 90° (a writer's choice)
    b = read_assembly(board(board_shape=turned))
    identify(b, None, previous=scene)
    by_a, by_b = {n.name: n for n in a.nodes}, {n.name: n for n in b.nodes}
    assert by_b["substrate"].uuid == by_a["substrate"].uuid and by_b["substrate"].match == "shape"


def test_one_of_eight_washers_deleted_removes_exactly_that_one() -> None:
    a, scene = first(board(washers=8))
    assy = board(washers=8)
    del assy.objects["washer_5"]
    assy.children = [c for c in assy.children if c.name != "washer_5"]
    b = read_assembly(assy)
    identify(b, None, previous=scene)
    gone = {n.uuid for n in a.nodes} - {n.uuid for n in b.nodes}
    assert gone == {next(n.uuid for n in a.nodes if n.name == "washer_5")}
    assert {n.name: n.uuid for n in a.nodes if n.name != "washer_5"} == {n.name: n.uuid for n in b.nodes}


def test_deleted_led_among_renumbered_ids_removes_only_it() -> None:
    a, scene = first(board(names=[f"NAUO{i}" for i in range(12)]))
    b = read_assembly(board(drop=4, names=[f"NAUO{i}" for i in range(12)][:4] + [f"NAUO{i - 1}" for i in range(5, 13)]
                            + ["x"]))
    identify(b, None, previous=scene)
    wa, wb = world_of(a), world_of(b)
    assert len(wa) - len(wb) == 1
    for u, p in wb.items():
        np.testing.assert_allclose(p, wa[u], atol=1e-6)


def test_two_identical_parts_swapped_in_place_are_reported_ambiguous() -> None:
    a, scene = first(board())
    names = [f"D{i + 1}" for i in range(12)]
    names[0], names[1] = names[1], names[0]
    b = read_assembly(board(names=names))
    identify(b, None, previous=scene)
    amb = {x["path"] for x in b.reconciliation["ambiguous"]}
    assert amb == {"pcb/D1", "pcb/D2"}
    for x in b.reconciliation["ambiguous"]:
        assert len(x["candidates"]) == 2 and "swapped" in x["reason"]
    # no part silently took another's UUID: each UUID is still at its old place in the world
    wa, wb = world_of(a), world_of(b)
    for u, p in wb.items():
        np.testing.assert_allclose(p, wa[u], atol=1e-6)


def test_resized_part_while_ids_are_renumbered_is_the_same_node() -> None:
    ids = [f"NAUO{i}" for i in range(12)]
    a, scene = first(board(names=ids))
    longer = cq.Workplane().box(88, 50, 1.6)  # 10 % longer
    b = read_assembly(board(board_shape=longer, drop=0, names=["x"] + [f"NAUO{i - 1}" for i in range(1, 12)]))
    identify(b, None, previous=scene)
    by_a, by_b = {n.name: n for n in a.nodes}, {n.name: n for n in b.nodes}
    assert by_b["substrate"].uuid == by_a["substrate"].uuid and by_b["substrate"].match == "structure"


def test_placement_within_tolerance_is_kept_bit_for_bit() -> None:
    a, scene = first(board())
    nudge = np.eye(4)
    nudge[:3, 3] = (3e-9, 0, 0)  # far below 1e-6 of the ~95 mm diagonal
    b = read_assembly(board(whole=nudge))
    identify(b, None, previous=scene)
    assert b.reconciliation_detail["snapped"] == len(b.nodes) - 1  # every child; the root did not move
    for na, nb in zip(a.nodes, b.nodes, strict=True):
        assert np.array_equal(na.transform, nb.transform)
    far = np.eye(4)
    far[:3, 3] = (1e-3, 0, 0)  # a real move stays a move
    c = read_assembly(board(whole=far))
    identify(c, None, previous=scene)
    assert c.reconciliation_detail["snapped"] == 0


def test_same_brep_keeps_the_scenes_geometry_id_and_an_edit_does_not() -> None:
    a, scene = first(board())
    b = read_assembly(board())
    identify(b, None, previous=scene, reuse_geometry=True)
    assert set(b.reuse) == set(b.parts)
    assert {b.reuse[n.part] for n in b.nodes if n.part} == {r["geometry"] for r in scene if r["geometry"]}
    c = read_assembly(board(board_shape=cq.Workplane().box(80, 50, 1.7)))
    identify(c, None, previous=scene, reuse_geometry=True)
    sub = next(n for n in c.nodes if n.name == "substrate")
    assert sub.part not in c.reuse and len(c.reuse) == len(c.parts) - 1


@needs_fixtures
@pytest.mark.parametrize("path", [STAMP, AS1], ids=["Stamp-S3", "as1"])
def test_real_assembly_turned_as_a_whole_keeps_every_uuid_in_place(path) -> None:
    """Stamp-S3 (Creo board) and as1 (CAX-IF; its unambiguous parts lie on one line, so only their principal
    axes fix the turn): the whole model turned 90° about Z by its writer, baked into the top placements."""
    a = read_step(path)
    identify(a, None)
    scene = records(a)
    b = read_step(path)
    turn = rz(90.0)
    root = next(n for n in b.nodes if n.parent is None)
    for n in b.nodes:
        if n.parent == root.index:
            n.transform = turn @ n.transform
    counts = identify(b, None, previous=scene)
    assert counts["new"] == 0 and not b.reconciliation["ambiguous"]
    wa, wb = world_of(a), world_of(b)
    moved_ok = sum(np.allclose(p, (turn @ np.append(wa[u], 1.0))[:3], atol=1e-4) for u, p in wb.items())
    assert moved_ok == len(wb)


def test_writer_ids_are_not_names_for_people() -> None:
    assert is_writer_id("") and is_writer_id("334") and is_writer_id("NAUO61") and is_writer_id("=>[0:1:1:3]")
    assert not is_writer_id("lens") and not is_writer_id("R0402")
    assert display_name("NAUO61", "headlamp_lens") == "headlamp_lens"
    assert display_name("left lens", "headlamp_lens") == "left lens"


def test_alignment_ignores_parts_moved_alone() -> None:
    rng = np.random.default_rng(1)
    p = rng.uniform(-1, 1, (20, 3))
    t = rz(33.0)
    t[:3, 3] = (0.5, -2, 1)
    q = p @ t[:3, :3].T + t[:3, 3]
    q[:5] += rng.uniform(0.2, 0.5, (5, 3))  # five parts the user moved
    found, inliers = robust_alignment(p, q, tol=1e-6)
    assert inliers == 15
    np.testing.assert_allclose(found, t, atol=1e-9)
    np.testing.assert_allclose(kabsch(p[5:], q[5:]), t, atol=1e-9)


def test_sparse_assignment_is_optimal_not_greedy() -> None:
    # greedy takes (0, 0) at cost 1 and must then pay 10 for (1, 1); the optimum is 2 + 2
    rows, cols = np.array([0, 0, 1, 1]), np.array([0, 1, 0, 1])
    cost = np.array([1.0, 2.0, 2.0, 10.0])
    assert sparse_assignment(rows, cols, cost, 2, 2, unmatched=50.0).tolist() == [1, 0]
    # leaving a row out is cheaper than a far match
    assert sparse_assignment(np.array([0]), np.array([0]), np.array([9.0]), 1, 1, unmatched=1.0).tolist() == [-1]


def test_bad_previous_records_are_refused_clearly() -> None:
    from cad_adapter.errors import IdentityError

    doc = read_assembly(board())
    with pytest.raises(IdentityError, match="no valid uuid"):
        identify(doc, None, previous=[{"uuid": "nope", "parent": None}])


def test_orphaned_assignments_are_reported_with_their_node_paths() -> None:
    from cad_adapter.cli import orphan_report

    u = "0b9d3f4e-5a6b-4c7d-8e9f-0a1b2c3d4e5f"
    answer = {"orphaned": [{"kind": "material", "id": u, "node": u}]}
    lines = orphan_report(answer, [{"uuid": u, "path": "lamp/reflector"}])
    assert len(lines) == 1 and "ORPHANED" in lines[0] and "'lamp/reflector'" in lines[0]
    assert orphan_report({"orphaned": []}, None) == []


def test_a_part_exactly_between_two_identical_ones_is_ambiguous_and_a_clear_move_is_not() -> None:
    """Ambiguous only on a true tie: LEDs D1 and D2 both moved onto the plane halfway between their old places
    (D2 10 mm above D1), so either assignment costs the same; D1 moved 5 mm off the grid has one best match."""
    a, scene = first(board())
    led = {n.name: n for n in a.nodes}

    def moved(shift_d1, shift_d2=(0.0, 0.0, 0.0)):
        assy = board()
        for name, shift in (("D1", shift_d1), ("D2", shift_d2)):
            m = np.eye(4)
            m[:3, 3] = (-24 + 16 * int(name == "D2"), -12, 1.4)
            m[:3, 3] += shift
            assy.objects[name].loc = loc_of(m)
        return read_assembly(assy)

    clear = moved((0.0, 5.0, 0.0))
    identify(clear, None, previous=scene)
    assert clear.reconciliation["ambiguous"] == []
    assert {n.name: n.uuid for n in clear.nodes} == {n.name: n.uuid for n in a.nodes}
    # D1 halfway to D2's old place, D2 halfway back and 10 mm up: each is as far from both old places
    tie = moved((8.0, 0.0, 0.0), (-8.0, 0.0, 10.0))
    identify(tie, None, previous=scene)
    amb = {x["path"]: x for x in tie.reconciliation["ambiguous"]}
    assert set(amb) == {"pcb/D1", "pcb/D2"}
    assert set(amb["pcb/D1"]["candidates"]) == {led["D1"].uuid, led["D2"].uuid}


@needs_fixtures
@pytest.mark.parametrize("drop_product", [True, False], ids=["deleted", "moved-out"])
def test_as1_subassembly_deleted_then_back_is_restored_and_nothing_is_ambiguous(tmp_path, drop_product) -> None:
    """CAX-IF as1 with rod-assembly_1 deleted in OCCT's XCAF editor (its product too, or left as a root at the
    origin), then the original again: every node keeps the UUID of the first push; the nodes the scene removed
    come back from its memory (``restored``); no match is reported ambiguous, and every part that did not move
    is matched to itself (its world centroid unchanged)."""
    from cad_helpers import xcaf_without

    a = read_step(AS1)
    identify(a, None)
    scene = records(a)
    cut = tmp_path / "cut.stp"
    xcaf_without(AS1, cut, "rod-assembly_1", drop_product=drop_product)
    b = read_step(cut)
    identify(b, None, previous=scene)
    assert b.reconciliation["ambiguous"] == []
    wa, wb = world_of(a), world_of(b)
    rod = {n.uuid for n in a.nodes if n.path.startswith("as1/rod-assembly_1")}
    for u, p in wb.items():
        if u not in rod:
            np.testing.assert_allclose(p, wa[u], atol=1e-6)
    present = {n.uuid for n in b.nodes}
    gone = [r for r in scene if r["uuid"] not in present]
    assert len(gone) == (3 if drop_product else 0)
    c = read_step(AS1)
    counts = identify(c, None, previous=records(b), removed=gone)
    assert counts["restored"] == len(gone) and counts["new"] == 0 and c.reconciliation["ambiguous"] == []
    assert [n.uuid for n in c.nodes] == [n.uuid for n in a.nodes]


def test_a_removed_part_that_comes_back_elsewhere_is_new() -> None:
    """Restored only within tolerance: an LED deleted and added back 3 mm away is a new node."""
    a, scene = first(board())
    b = read_assembly(board(drop=4))
    identify(b, None, previous=scene)
    gone = [r for r in scene if r["uuid"] not in {n.uuid for n in b.nodes}]
    assert [r["path"] for r in gone] == ["pcb/D5"]
    back = board()
    m = np.eye(4)
    m[:3, 3] = (-24.0, 3.0, 1.4)  # D5's place is (-24, 0, 1.4)
    back.objects["D5"].loc = loc_of(m)
    c = read_assembly(back)
    counts = identify(c, None, previous=records(b), removed=gone)
    assert counts["restored"] == 0 and counts["new"] == 1
    d = read_assembly(board())
    counts = identify(d, None, previous=records(b), removed=gone)
    assert counts["restored"] == 1 and {n.name: n.uuid for n in d.nodes}["D5"] == gone[0]["uuid"]
