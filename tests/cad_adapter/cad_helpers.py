"""Shared helpers of the CAD adapter tests: fixture paths, cached sample builds, coarse settings."""

from __future__ import annotations

import functools

import pytest
from conftest import SHARED_FIXTURES

STEP_DIR = SHARED_FIXTURES / "step"
AS1 = STEP_DIR / "as1-oc-214.stp"
STAMP = STEP_DIR / "Stamp-S3.step"
SERVO = STEP_DIR / "STS3215_03a.step"
CUBE_CYL = STEP_DIR / "red_cube_blue_cylinder.step"
S1C5 = STEP_DIR / "s1-c5-214" / "s1-c5-214.stp"

needs_fixtures = pytest.mark.skipif(not STEP_DIR.is_dir(), reason=f"shared STEP fixtures not found at {STEP_DIR}")

#: coarse tessellation for quick tests (document units: mm)
COARSE = {"linear": 1.0, "angular": 0.8}


@functools.lru_cache(maxsize=8)
def car(door_angle_deg: float = 0.0, lens_radius_mm: float = 120.0):
    """The sample car (cached: building it costs seconds). Callers must not modify it."""
    from cad_adapter.samples import car_assembly

    return car_assembly(door_angle_deg=door_angle_deg, lens_radius_mm=lens_radius_mm)


def xcaf_without(src, dst, name: str, drop_product: bool = True) -> None:
    """Delete the top-level component ``name`` in OCCT's XCAF document of ``src`` and write ``dst`` with OCCT's
    writer (a CAD tool's "delete, save": the component and its product go; a part it held that has no other use
    stays as a free root, as OCCT leaves it; instance ids renumbered). ``drop_product=False``: the product stays,
    as a free root at the origin (the whole sub-assembly moved out of the model)."""
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.STEPCAFControl import STEPCAFControl_Writer
    from OCP.STEPControl import STEPControl_AsIs
    from OCP.TDataStd import TDataStd_Name
    from OCP.TDF import TDF_Label, TDF_LabelSequence
    from OCP.XCAFDoc import XCAFDoc_DocumentTool, XCAFDoc_ShapeTool

    from cad_adapter.step_reader import read_xcaf

    doc, _, _, _ = read_xcaf(src)
    tool = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    roots = TDF_LabelSequence()
    tool.GetFreeShapes(roots)

    def name_of(label) -> str:
        attr = TDataStd_Name()
        return attr.Get().ToExtString() if label.FindAttribute(TDataStd_Name.GetID_s(), attr) else ""

    found = 0
    for i in range(1, roots.Length() + 1):
        comps = TDF_LabelSequence()
        XCAFDoc_ShapeTool.GetComponents_s(roots.Value(i), comps, False)
        for k in range(1, comps.Length() + 1):
            if name_of(comps.Value(k)) == name:
                ref = TDF_Label()
                XCAFDoc_ShapeTool.GetReferredShape_s(comps.Value(k), ref)
                tool.RemoveComponent(comps.Value(k))
                tool.UpdateAssemblies()
                if drop_product:
                    tool.RemoveShape(ref, True)
                found += 1
    assert found == 1, f"{found} components named {name!r}"
    tool.UpdateAssemblies()
    writer = STEPCAFControl_Writer()
    writer.SetNameMode(True)
    writer.SetColorMode(True)
    assert writer.Transfer(doc, STEPControl_AsIs)
    assert writer.Write(str(dst)) == IFSelect_RetDone


def xcaf_round_trip(src, dst) -> None:
    """Read a STEP file into OCCT's XCAF document and write it again with OCCT's own writer (another writer:
    instance ids renumbered, entities reordered; on Stamp-S3 it splits one edge of the board), with no edit."""
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.STEPCAFControl import STEPCAFControl_Writer
    from OCP.STEPControl import STEPControl_AsIs

    from cad_adapter.step_reader import read_xcaf

    doc, _, _, _ = read_xcaf(src)
    writer = STEPCAFControl_Writer()
    writer.SetNameMode(True)
    writer.SetColorMode(True)
    assert writer.Transfer(doc, STEPControl_AsIs)
    assert writer.Write(str(dst)) == IFSelect_RetDone
