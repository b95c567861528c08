"""UUIDs carried inside STEP files: the writer that puts them in (the reader's side that finds them is
:func:`cad_adapter.xcaf.carried_uuids`, which :func:`cad_adapter.step_reader.read_step` calls).

Where the UUIDs go (OCP allows it through the STEP model the XCAF writer builds, before it is written):

* a component occurrence (``NEXT_ASSEMBLY_USAGE_OCCURRENCE``): its ``id`` attribute holds the node's UUID;
* a root (a free ``PRODUCT`` with no parent): the product's ``id`` holds the root node's UUID.

The writer names each XCAF label with a unique token while transferring, finds the entity that carries
the token in the STEP model, moves the UUID into its ``id`` and restores the real name, so names in the
file stay what the document had.

Limit: a NAUO is one usage of a product in its parent *product*; when a sub-assembly is used several
times (as1-oc-214's nut-bolt assembly) its inner NAUOs are shared by all its occurrences, so a UUID there
would be ambiguous. The reader therefore applies a carried UUID only to a component that occurs exactly
once in the tree; the others fall back on the sidecar. The writer writes the tree it is given (one
product per part, one per assembly node), where every NAUO is one occurrence.
"""

from __future__ import annotations

from pathlib import Path

from OCP.BRepBuilderAPI import BRepBuilderAPI_Copy
from OCP.gp import gp_Trsf
from OCP.IFSelect import IFSelect_RetDone
from OCP.Interface import Interface_Static
from OCP.Quantity import Quantity_Color, Quantity_TOC_RGB
from OCP.StepBasic import StepBasic_Product
from OCP.STEPCAFControl import STEPCAFControl_Writer
from OCP.STEPControl import STEPControl_AsIs
from OCP.StepRepr import StepRepr_NextAssemblyUsageOccurrence
from OCP.TCollection import TCollection_ExtendedString, TCollection_HAsciiString
from OCP.TDataStd import TDataStd_Name
from OCP.TDF import TDF_Label
from OCP.TDocStd import TDocStd_Document
from OCP.TopLoc import TopLoc_Location
from OCP.XCAFApp import XCAFApp_Application
from OCP.XCAFDoc import XCAFDoc_ColorSurf, XCAFDoc_ColorTool, XCAFDoc_DocumentTool, XCAFDoc_ShapeTool
from OCP.XSControl import XSControl_WorkSession

from .errors import CadAdapterError
from .tree import UNIT_METRES, Document
from .xcaf import entities, entity_text

_STEP_UNIT = {"mm": "MM", "cm": "CM", "m": "M", "um": "UM", "in": "INCH", "ft": "FT"}


def _set_name(label, text: str) -> None:
    TDataStd_Name.Set_s(label, TCollection_ExtendedString(text))


def _location(m) -> TopLoc_Location:
    """OCCT's location of a node's 4x4 transform (its upper 3x4 block)."""
    t = gp_Trsf()
    t.SetValues(*[float(m[r, c]) for r in range(3) for c in range(4)])
    return TopLoc_Location(t)


def _check_writable(doc: Document) -> None:
    """Refuse a document the writer cannot carry faithfully, before any OCCT work is spent on it."""
    if any(n.uuid is None for n in doc.nodes):
        raise CadAdapterError("every node needs a UUID before writing (run cad_adapter.identity.identify)")
    if doc.length_unit not in UNIT_METRES:
        raise CadAdapterError(f"unknown length unit {doc.length_unit!r}")


def _new_xcaf_document(length_unit: str) -> tuple[TDocStd_Document, XCAFDoc_ShapeTool, XCAFDoc_ColorTool]:
    """An empty XCAF document in the document's unit, with its shape tool (no automatic names: the writer
    names every label itself) and colour tool."""
    app = XCAFApp_Application.GetApplication_s()
    xdoc = TDocStd_Document(TCollection_ExtendedString("XmlXCAF"))
    app.InitDocument(xdoc)
    XCAFDoc_DocumentTool.SetLengthUnit_s(xdoc, UNIT_METRES[length_unit])
    tool = XCAFDoc_DocumentTool.ShapeTool_s(xdoc.Main())
    tool.SetAutoNaming_s(False)
    ctool = XCAFDoc_DocumentTool.ColorTool_s(xdoc.Main())
    return xdoc, tool, ctool


def _add_parts(doc: Document, tool: XCAFDoc_ShapeTool, ctool: XCAFDoc_ColorTool) -> dict[str, TDF_Label]:
    """One XCAF shape per part (so that its nodes share one product in the file); returns part key -> label."""
    part_labels = {}
    for key, part in doc.parts.items():
        # a deep copy: the STEP writer's shape processing adjusts tolerances in place
        lab = tool.AddShape(BRepBuilderAPI_Copy(part.shape, True, False).Shape(), False, False)
        _set_name(lab, part.name or key)
        if XCAFDoc_ShapeTool.IsReference_s(lab):  # a located shape: name its prototype too
            proto = TDF_Label()
            XCAFDoc_ShapeTool.GetReferredShape_s(lab, proto)
            _set_name(proto, part.name or key)
        if part.color is not None:
            ctool.SetColor(lab, Quantity_Color(*part.color, Quantity_TOC_RGB), XCAFDoc_ColorSurf)
        part_labels[key] = lab
    return part_labels


def _add_nodes(doc: Document, tool: XCAFDoc_ShapeTool, ctool: XCAFDoc_ColorTool,
               part_labels: dict[str, TDF_Label]) -> dict[str, tuple[str, str]]:
    """Build the node tree on the parts, naming each node's label (a root's shape, another node's component)
    with a unique token so that its STEP entity can be found after the transfer; returns token -> (uuid,
    real name)."""
    tokens: dict[str, tuple[str, str]] = {}
    node_labels = {}
    for n in doc.nodes:
        token = f"LLTOKEN{n.index:08d}"
        tokens[token] = (n.uuid, n.name)
        kids = doc.children(n.index)
        if n.parent is None:
            # a root: a free assembly label (even for a single part, so that the product id can carry its UUID)
            lab = tool.NewShape()
            _set_name(lab, token)
            node_labels[n.index] = lab
            if n.part is not None:
                comp = tool.AddComponent(lab, part_labels[n.part], _location(n.transform))
                _set_name(comp, n.name)
            continue
        parent_lab = node_labels[n.parent]
        if n.part is not None and not kids:
            comp = tool.AddComponent(parent_lab, part_labels[n.part], _location(n.transform))
        else:
            sub = tool.NewShape()
            _set_name(sub, n.name)
            node_labels[n.index] = sub
            if n.part is not None:
                tool.AddComponent(sub, part_labels[n.part], TopLoc_Location())
            comp = tool.AddComponent(parent_lab, sub, _location(n.transform))
        _set_name(comp, token)
        if n.color is not None and (n.part is None or n.color != doc.parts[n.part].color):
            ctool.SetColor(comp, Quantity_Color(*n.color, Quantity_TOC_RGB), XCAFDoc_ColorSurf)
    tool.UpdateAssemblies()
    return tokens


def _transfer(xdoc: TDocStd_Document, length_unit: str) -> STEPCAFControl_Writer:
    """Translate the XCAF document into an AP214 STEP model (names and colours kept), not yet written, so
    that its entities can still be edited."""
    session = XSControl_WorkSession()
    writer = STEPCAFControl_Writer(session, False)
    writer.SetNameMode(True)
    writer.SetColorMode(True)
    Interface_Static.SetCVal_s("write.step.schema", "AP214IS")
    Interface_Static.SetCVal_s("write.step.unit", _STEP_UNIT[length_unit])
    if not writer.Transfer(xdoc, STEPControl_AsIs):
        raise CadAdapterError("OCCT could not transfer the document to STEP")
    return writer


def _place_uuids(writer: STEPCAFControl_Writer, tokens: dict[str, tuple[str, str]], carry_uuids: bool) -> int:
    """Swap each token in the STEP model (a NAUO's or a product's name) for the node's real name, and put its
    UUID into the entity's id when ``carry_uuids``; returns how many tokens were found."""
    found = 0
    for ent in entities(writer.ChangeWriter().Model()):
        if isinstance(ent, StepRepr_NextAssemblyUsageOccurrence | StepBasic_Product):
            name = entity_text(ent.Name())
            if name in tokens:
                uuid, real = tokens[name]
                if carry_uuids:
                    ent.SetId(TCollection_HAsciiString(uuid))
                ent.SetName(TCollection_HAsciiString(real))
                found += 1
    return found


def _write_file(writer: STEPCAFControl_Writer, path: str | Path) -> Path:
    """Write the model, now carrying the UUIDs, to ``path``; OCCT's failure code becomes an error."""
    p = Path(path)
    if writer.Write(str(p)) != IFSelect_RetDone:
        raise CadAdapterError(f"{p}: OCCT could not write the STEP file")
    return p


def write_step(doc: Document, path: str | Path, carry_uuids: bool = True) -> Path:
    """Write a document (with UUIDs assigned) as STEP AP214, each node's UUID carried in the file.

    Parameters
    ----------
    doc : Document
        Read from STEP or cadquery; every node needs ``uuid``. Parts keep their instancing (one product
        per part, one occurrence per node).
    path : path
        Output file (overwritten).
    carry_uuids : bool
        False: write no UUID (OCCT's own ids, as any re-export through OCCT): what a CAD tool's "save" gives.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    CadAdapterError
        A node without UUID, or OCCT fails to write.
    """
    _check_writable(doc)
    xdoc, tool, ctool = _new_xcaf_document(doc.length_unit)
    part_labels = _add_parts(doc, tool, ctool)
    tokens = _add_nodes(doc, tool, ctool, part_labels)
    writer = _transfer(xdoc, doc.length_unit)
    found = _place_uuids(writer, tokens, carry_uuids)
    p = _write_file(writer, path)  # before the count check, as it always was: a short count leaves the file behind
    if found < len(doc.nodes):
        raise CadAdapterError(f"only {found} of {len(doc.nodes)} node UUIDs could be placed in the STEP model")
    return p
