"""Reading STEP fixtures and cadquery assemblies: tree shape, instancing, units, colours, bad input."""

from __future__ import annotations

import os
from pathlib import Path

import cadquery as cq
import numpy as np
import pytest
from cad_helpers import AS1, CUBE_CYL, S1C5, SERVO, STAMP, car, needs_fixtures

from cad_adapter.assembly import read_assembly
from cad_adapter.errors import CadImportError, EmptyDocumentError
from cad_adapter.step_reader import read_step
from cad_adapter.tessellate import has_faces

pytestmark = needs_fixtures


def test_as1_instancing_five_parts_eighteen_leaves() -> None:
    doc = read_step(AS1)
    assert doc.length_unit == "mm"
    assert len(doc.parts) == 5
    leaves = doc.leaves()
    assert len(leaves) == 18
    assert sorted({doc.parts[n.part].name for n in leaves}) == ["bolt", "l-bracket", "nut", "plate", "rod"]
    # the nut is used 8 times (2 in the rod assembly, 1 in each of 6 nut-bolt assemblies): one part, 8 nodes
    nut = next(k for k, p in doc.parts.items() if p.name == "nut")
    assert sum(n.part == nut for n in leaves) == 8
    # one root; assembly nodes carry no geometry; every parent precedes its children
    assert [n.path for n in doc.nodes if n.parent is None] == ["as1"]
    assert all(n.part is None for n in doc.nodes if doc.children(n.index))
    assert all(n.parent is None or n.parent < n.index for n in doc.nodes)
    # occurrence paths are unique, so they can identify nodes
    assert len({n.path for n in doc.nodes}) == len(doc.nodes)


def test_as1_instances_have_their_own_transforms() -> None:
    doc = read_step(AS1)
    nut = next(k for k, p in doc.parts.items() if p.name == "nut")
    worlds = [doc.world_transform(n.index) for n in doc.leaves() if n.part == nut]
    origins = {tuple(np.round(w[:3, 3], 6)) for w in worlds}
    assert len(origins) == 8  # eight nuts in eight places
    for w in worlds:  # rigid motions
        r = w[:3, :3]
        np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-9)
        assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-9)


def test_two_free_roots_and_face_colours() -> None:
    doc = read_step(CUBE_CYL)
    assert sorted(n.path for n in doc.nodes) == ["blue_cylinder", "red_cube"]
    assert all(n.parent is None and n.part is not None for n in doc.nodes)
    assert doc.length_unit == "m"
    colours = {n.name: n.color for n in doc.nodes}
    r, g, b = colours["red_cube"]
    assert r > 0.5 and g < 0.2 and b < 0.2  # colours sit on the faces only
    r, g, b = colours["blue_cylinder"]
    assert b > 0.3 and b > 3 * r
    # lengths are in the file's own unit (metres): the cube is 1 cm across
    sig = doc.parts[next(n.part for n in doc.nodes if n.name == "red_cube")].shape
    from cad_adapter.identity import shape_signature

    bbox = shape_signature(sig)["bbox"]
    assert bbox[3] - bbox[0] == pytest.approx(0.01, rel=1e-6)


def test_stamp_faceless_leaves_are_nodes_without_faces() -> None:
    doc = read_step(STAMP)
    faceless = [k for k, p in doc.parts.items() if not has_faces(p.shape)]
    assert len(faceless) == 4
    assert any("without faces" in w for w in doc.warnings)
    assert len(doc.parts) == 33
    assert any(any(ord(ch) > 127 for ch in n.name) for n in doc.nodes)  # the non-ASCII name survives


def test_external_references_resolve_from_any_working_directory(monkeypatch) -> None:
    # a relative path with a directory is the case OCCT resolves to empty shapes unless made absolute
    monkeypatch.chdir(S1C5.parent.parent)
    doc = read_step(Path(S1C5.parent.name) / S1C5.name)
    assert doc.length_unit == "in"
    assert len(doc.leaves()) == 11
    assert all(has_faces(p.shape) for p in doc.parts.values())


def test_single_part_document() -> None:
    doc = read_step(SERVO)
    assert len(doc.nodes) == 1 and doc.nodes[0].part is not None


def test_missing_file() -> None:
    with pytest.raises(CadImportError, match="no such file"):
        read_step("/nonexistent/x.step")


def test_directory(tmp_path) -> None:
    with pytest.raises(CadImportError, match="directory"):
        read_step(tmp_path)


def test_empty_file(tmp_path) -> None:
    p = tmp_path / "empty.step"
    p.write_bytes(b"")
    with pytest.raises(CadImportError, match="empty"):
        read_step(p)


def test_not_step(tmp_path) -> None:
    p = tmp_path / "mesh.step"
    p.write_text("solid cube\nfacet normal 0 0 1\nendsolid\n")
    with pytest.raises(CadImportError, match="not a STEP file"):
        read_step(p)


def test_unreadable_file(tmp_path) -> None:
    if os.geteuid() == 0:
        pytest.skip("root reads files whatever their mode")
    p = tmp_path / "locked.step"
    p.write_bytes(AS1.read_bytes()[:100])
    p.chmod(0)
    with pytest.raises(CadImportError, match="cannot be read"):
        read_step(p)


def test_step_without_shapes(tmp_path) -> None:
    p = tmp_path / "nothing.step"
    p.write_text("ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION(('empty'),'2;1');\nFILE_NAME('nothing','',(''),(''),'',"
                 "'','');\nFILE_SCHEMA(('AUTOMOTIVE_DESIGN'));\nENDSEC;\nDATA;\nENDSEC;\nEND-ISO-10303-21;\n")
    with pytest.raises(EmptyDocumentError):
        read_step(p)


def test_truncated_step_is_a_clear_error(tmp_path) -> None:
    p = tmp_path / "cut.step"
    p.write_bytes(AS1.read_bytes()[:2000])
    with pytest.raises(CadImportError):
        read_step(p)


def test_car_sample_tree() -> None:
    doc = read_assembly(car())
    assert doc.length_unit == "mm"
    paths = [n.path for n in doc.nodes]
    assert paths == ["car", "car/body", "car/door_left", "car/door_right", "car/wheel_fl", "car/wheel_fr",
                     "car/wheel_rl", "car/wheel_rr", "car/windscreen", "car/headlamp", "car/headlamp/housing",
                     "car/headlamp/lens"]
    wheels = [n for n in doc.nodes if n.name.startswith("wheel_")]
    assert len({n.part for n in wheels}) == 1  # four instances of one part
    assert len(doc.parts) == 7
    assert len({tuple(n.transform[:3, 3]) for n in wheels}) == 4


def test_assembly_bad_input() -> None:
    with pytest.raises(CadImportError, match="cadquery.Assembly"):
        read_assembly("car.step")  # type: ignore[arg-type]
    with pytest.raises(CadImportError, match="unknown length unit"):
        read_assembly(car(), length_unit="furlong")
    with pytest.raises(EmptyDocumentError):
        read_assembly(cq.Assembly(name="nothing"))


def test_duplicate_sibling_names_get_ranked_paths(tmp_path) -> None:
    text = AS1.read_text().replace("'nut_1'", "'nut'").replace("'nut_2'", "'nut'")
    p = tmp_path / "dup.stp"
    p.write_text(text)
    doc = read_step(p)
    rod = [n.path for n in doc.nodes if n.path.startswith("as1/rod-assembly_1/")]
    assert rod == ["as1/rod-assembly_1/nut", "as1/rod-assembly_1/nut[2]", "as1/rod-assembly_1/rod_1"]
    assert len({n.path for n in doc.nodes}) == len(doc.nodes)
