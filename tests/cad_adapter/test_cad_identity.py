"""UUID identity: stable across re-import, move, rename, reorder, delete-and-restore; carried UUIDs win."""

from __future__ import annotations

import json
import shutil
import uuid
from pathlib import Path

import cadquery as cq
import pytest
from cad_helpers import AS1, needs_fixtures

from cad_adapter.assembly import read_assembly
from cad_adapter.errors import IdentityError
from cad_adapter.identity import identify, load_sidecar, sidecar_path
from cad_adapter.step_reader import read_step

PLATE = cq.Workplane().box(100, 60, 5)
PEG = cq.Workplane().circle(4).extrude(20)
CUP = cq.Workplane().box(20, 20, 10).faces(">Z").shell(-1)
LENS = cq.Workplane().sphere(12).intersect(cq.Workplane().box(30, 30, 10).translate((0, 0, 8)))


def rig(names: dict[str, str] | None = None, order: list[str] | None = None, moves: dict[str, float] | None = None,
        drop: tuple[str, ...] = (), metadata: dict[str, dict] | None = None) -> cq.Assembly:
    """A small assembly: plate, three instances of one peg, and a lamp sub-assembly (cup + lens).

    ``names`` renames nodes, ``order`` reorders the root's children, ``moves`` shifts nodes along x,
    ``drop`` leaves nodes out, ``metadata`` sets node metadata (all by the default names).
    """
    names, moves, metadata = names or {}, moves or {}, metadata or {}
    children = {
        "plate": (PLATE, (0, 0, 0)),
        "peg_a": (PEG, (-30, 0, 2.5)),
        "peg_b": (PEG, (0, 0, 2.5)),
        "peg_c": (PEG, (30, 0, 2.5)),
        "lamp": (None, (0, 40, 0)),
    }
    root = cq.Assembly(name=names.get("rig", "rig"))
    for key in order or list(children):
        if key in drop:
            continue
        obj, (x, y, z) = children[key]
        loc = cq.Location((x + moves.get(key, 0.0), y, z))
        if obj is None:
            lamp = cq.Assembly(name=names.get("lamp", "lamp"), loc=loc, metadata=metadata.get("lamp"))
            lamp.add(CUP, name=names.get("cup", "cup"), metadata=metadata.get("cup"))
            lamp.add(LENS, name=names.get("lens", "lens"), loc=cq.Location((0, 0, moves.get("lens", 0.0))),
                     metadata=metadata.get("lens"))
            root.add(lamp, name=names.get("lamp", "lamp"))
        else:
            root.add(obj, name=names.get(key, key), loc=loc, metadata=metadata.get(key))
    return root


def uuids(doc, by: str = "path") -> dict[str, str]:
    return {getattr(n, by) if by != "leaf" else n.path.rsplit("/", 1)[-1]: n.uuid for n in doc.nodes}


def first_import(tmp_path, assy=None):
    side = tmp_path / "rig.lumenlink.json"
    doc = read_assembly(assy or rig())
    counts = identify(doc, side)
    assert counts["new"] == len(doc.nodes)
    return doc, side


def test_reimport_keeps_every_uuid_by_path(tmp_path) -> None:
    a, side = first_import(tmp_path)
    b = read_assembly(rig())
    counts = identify(b, side)
    assert counts["new"] == 0 and counts["shape"] + counts["placement"] == len(b.nodes)
    assert uuids(a) == uuids(b)


def test_moved_node_keeps_uuid(tmp_path) -> None:
    a, side = first_import(tmp_path)
    b = read_assembly(rig(moves={"peg_b": 7.0, "lens": 3.0}))
    identify(b, side)
    assert uuids(a) == uuids(b)
    assert {n.match for n in b.nodes} <= {"shape", "placement"}


def test_renamed_instance_keeps_uuid_by_signature_and_position(tmp_path) -> None:
    # three pegs share one signature: the renamed one must get the UUID of the peg at its place
    a, side = first_import(tmp_path)
    b = read_assembly(rig(names={"peg_b": "middle_peg"}))
    identify(b, side)
    ua, ub = uuids(a), uuids(b)
    assert ub["rig/middle_peg"] == ua["rig/peg_b"]
    assert next(n for n in b.nodes if n.name == "middle_peg").match == "placement"
    assert ub["rig/peg_a"] == ua["rig/peg_a"] and ub["rig/peg_c"] == ua["rig/peg_c"]


def test_renamed_and_moved_instance_picks_nearest(tmp_path) -> None:
    a, side = first_import(tmp_path)
    b = read_assembly(rig(names={"peg_c": "right_peg"}, moves={"peg_c": 2.0}))
    identify(b, side)
    assert uuids(b)["rig/right_peg"] == uuids(a)["rig/peg_c"]


def test_renamed_subassembly_keeps_its_and_its_childrens_uuids(tmp_path) -> None:
    a, side = first_import(tmp_path)
    b = read_assembly(rig(names={"lamp": "headlamp"}))
    identify(b, side)
    ua, ub = uuids(a), uuids(b)
    assert ub["rig/headlamp"] == ua["rig/lamp"]
    assert ub["rig/headlamp/cup"] == ua["rig/lamp/cup"] and ub["rig/headlamp/lens"] == ua["rig/lamp/lens"]
    matches = {n.path: n.match for n in b.nodes}
    assert matches["rig/headlamp"] == "shape" and matches["rig/headlamp/lens"] == "shape"


def test_reordered_children_keep_uuids(tmp_path) -> None:
    a, side = first_import(tmp_path)
    b = read_assembly(rig(order=["lamp", "peg_c", "plate", "peg_a", "peg_b"]))
    identify(b, side)
    assert [n.path for n in b.nodes] != [n.path for n in a.nodes]
    assert uuids(a) == uuids(b)


def test_deleted_then_restored_node_gets_its_uuid_back(tmp_path) -> None:
    a, side = first_import(tmp_path)
    b = read_assembly(rig(drop=("peg_b",)))
    identify(b, side)
    assert "rig/peg_b" not in uuids(b)
    absent = [e for e in load_sidecar(side)["nodes"] if not e["present"]]
    assert [e["path"] for e in absent] == ["rig/peg_b"]
    c = read_assembly(rig())
    identify(c, side)
    assert uuids(c) == uuids(a)


def test_edited_part_keeps_uuid(tmp_path) -> None:
    # a new shape at the same path is the same node with new geometry
    a, side = first_import(tmp_path)
    big = rig()
    big.objects["plate"].obj = cq.Workplane().box(120, 60, 5)
    b = read_assembly(big)
    identify(b, side)
    assert uuids(a) == uuids(b)


def test_carried_uuid_wins_and_duplicate_falls_back(tmp_path) -> None:
    u = str(uuid.uuid4())
    a, side = first_import(tmp_path)
    b = read_assembly(rig(metadata={"peg_a": {"uuid": u}, "peg_b": {"uuid": u.upper()}}))
    identify(b, side)
    by = {n.path: n for n in b.nodes}
    assert by["rig/peg_a"].uuid == u and by["rig/peg_a"].match == "carried"
    # the second use of the same UUID is not trusted: peg_b keeps its sidecar UUID
    assert by["rig/peg_b"].uuid == uuids(a)["rig/peg_b"] and by["rig/peg_b"].match == "placement"
    assert len({n.uuid for n in b.nodes}) == len(b.nodes)


def test_invalid_carried_uuid_is_ignored(tmp_path) -> None:
    b = read_assembly(rig(metadata={"plate": {"uuid": "not-a-uuid"}}))
    identify(b, None)
    assert next(n for n in b.nodes if n.name == "plate").match == "new"


def test_no_sidecar_means_new_uuids_each_time() -> None:
    a, b = read_assembly(rig()), read_assembly(rig())
    identify(a, None)
    identify(b, None)
    assert not set(uuids(a).values()) & set(uuids(b).values())


def test_corrupt_sidecar(tmp_path) -> None:
    side = tmp_path / "x.lumenlink.json"
    side.write_text("{not json")
    with pytest.raises(IdentityError, match="cannot be read"):
        identify(read_assembly(rig()), side)
    side.write_text(json.dumps({"format": "something-else", "nodes": []}))
    with pytest.raises(IdentityError, match="not a lumenlink-sidecar-v3"):
        identify(read_assembly(rig()), side)
    side.write_text(json.dumps({"format": "lumenlink-sidecar-v2", "nodes": [{"uuid": "x", "path": "rig"}]}))
    with pytest.raises(IdentityError, match="invalid uuid"):
        identify(read_assembly(rig()), side)


def test_unwritable_sidecar(tmp_path) -> None:
    with pytest.raises(IdentityError, match="cannot write the sidecar"):
        identify(read_assembly(rig()), tmp_path / "missing-dir" / "x.lumenlink.json")


@needs_fixtures
def test_step_reimport_and_renamed_occurrence(tmp_path) -> None:
    path = tmp_path / "as1.stp"
    shutil.copy(AS1, path)
    a = read_step(path)
    assert identify(a)["new"] == len(a.nodes)
    assert sidecar_path(path).exists()
    b = read_step(path)
    assert identify(b)["new"] == 0
    assert uuids(a) == uuids(b)
    # rename the plate's occurrence in the file itself
    path.write_text(path.read_text().replace("'plate_1'", "'base_plate'"))
    c = read_step(path)
    identify(c)
    uc = uuids(c)
    assert uc["as1/base_plate"] == uuids(a)["as1/plate_1"]
    assert next(n for n in c.nodes if n.name == "base_plate").match == "shape"
    assert set(uc.values()) == set(uuids(a).values())


def test_read_only_folder_keeps_the_sidecar_in_the_cache(tmp_path, monkeypatch) -> None:
    import os

    from cad_adapter.identity import default_sidecar

    folder = tmp_path / "ro"
    folder.mkdir()
    doc_path = folder / "car.step"
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if Path(p) == folder else real_access(p, mode))
    monkeypatch.setenv("LUMENLINK_SIDECAR_DIR", str(tmp_path / "cache"))
    path, warning = default_sidecar(doc_path)
    assert path.parent == tmp_path / "cache" and "not writable" in warning
    # beside the document when the folder is writable, and always the same place for the same document
    monkeypatch.setattr(os, "access", real_access)
    assert default_sidecar(doc_path) == (folder / "car.step.lumenlink.json", None)
