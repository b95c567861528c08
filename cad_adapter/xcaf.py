"""XCAF labels and STEP model entities, as the reader and the UUID writer both see them.

`label_name` and `label_entry` name an XCAF label; `entities` and `entity_text` walk the STEP model behind
a reader or writer; `carried_uuids` is the reader's side of the UUIDs that :mod:`cad_adapter.step_uuid`
writes into a file (where they go, and why a shared sub-assembly's inner UUIDs are not used, is told
there). :mod:`cad_adapter.step_reader` and :mod:`cad_adapter.step_uuid` both import this module and not
each other's internals.
"""

from __future__ import annotations

import re

from OCP.StepBasic import StepBasic_Product
from OCP.STEPCAFControl import STEPCAFControl_Reader
from OCP.STEPConstruct import STEPConstruct_Tool
from OCP.StepRepr import StepRepr_NextAssemblyUsageOccurrence
from OCP.TCollection import TCollection_AsciiString
from OCP.TDataStd import TDataStd_Name
from OCP.TDF import TDF_Label, TDF_LabelSequence, TDF_Tool
from OCP.TDocStd import TDocStd_Document
from OCP.XCAFDoc import XCAFDoc_DocumentTool

UUID_RE = re.compile(r"[0-9a-fA-F]{8}-[0-9a-fA-F]{4}-[0-9a-fA-F]{4}-[0-9a-fA-F]{4}-[0-9a-fA-F]{12}")


def label_name(label: TDF_Label) -> str:
    """The TDataStd_Name of a label, or ''."""
    attr = TDataStd_Name()
    if label.FindAttribute(TDataStd_Name.GetID_s(), attr):
        return str(attr.Get().ToExtString())
    return ""


def label_entry(label: TDF_Label) -> str:
    """The label's entry ('0:1:1:3'): unique within one document."""
    s = TCollection_AsciiString()
    TDF_Tool.Entry_s(label, s)
    return str(s.ToCString())


def entities(model):
    """The entities of a STEP model (an ``Interface_InterfaceModel``), first to last."""
    for i in range(1, model.NbEntities() + 1):
        yield model.Value(i)


def entity_text(h) -> str:
    """A STEP entity's string attribute (an ``HAsciiString`` or None) as text."""
    return "" if h is None else str(h.ToCString())


def carried_uuids(reader: STEPCAFControl_Reader, doc: TDocStd_Document) -> dict[str, str]:
    """UUIDs a read STEP file carries, by XCAF label entry (component labels and free-shape labels).

    A NAUO whose ``id`` is a UUID marks its component; a root product whose ``id`` is a UUID marks the
    free shape of the same name. Malformed or missing ids are ignored (the sidecar takes over).
    """
    ws = reader.ChangeReader().WS()
    model = reader.ChangeReader().Model()
    if model is None:
        return {}
    shape_tool = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    tool = STEPConstruct_Tool(ws)
    label_map = reader.GetShapeLabelMap()
    out: dict[str, str] = {}
    root_products: dict[str, str] = {}
    for ent in entities(model):
        if isinstance(ent, StepRepr_NextAssemblyUsageOccurrence):
            text = entity_text(ent.Id())
            if UUID_RE.fullmatch(text):
                try:
                    label = STEPCAFControl_Reader.FindInstance_s(ent, shape_tool, tool, label_map)
                except Exception:  # OCCT cannot place it: leave it to the sidecar
                    continue
                if not label.IsNull():
                    out[label_entry(label)] = text.lower()
        elif isinstance(ent, StepBasic_Product):
            text = entity_text(ent.Id())
            if UUID_RE.fullmatch(text):
                root_products.setdefault(entity_text(ent.Name()), text.lower())
    if root_products:
        labels = TDF_LabelSequence()
        shape_tool.GetFreeShapes(labels)
        for i in range(1, labels.Length() + 1):
            lab = labels.Value(i)
            u = root_products.get(label_name(lab))
            if u is not None:
                out.setdefault(label_entry(lab), u)
    return _only_single_occurrences(out, shape_tool)


def _only_single_occurrences(found: dict[str, str], shape_tool) -> dict[str, str]:
    """Drop component UUIDs whose component is reached more than once (a shared sub-assembly's inside)."""
    counts: dict[str, int] = {}

    def walk(label, depth: int) -> None:
        comps = TDF_LabelSequence()
        shape_tool.GetComponents_s(label, comps)
        for i in range(1, comps.Length() + 1):
            comp = comps.Value(i)
            e = label_entry(comp)
            counts[e] = counts.get(e, 0) + 1
            ref = TDF_Label()
            if shape_tool.GetReferredShape_s(comp, ref) and shape_tool.IsAssembly_s(ref) and depth < 64:
                walk(ref, depth + 1)

    labels = TDF_LabelSequence()
    shape_tool.GetFreeShapes(labels)
    for i in range(1, labels.Length() + 1):
        lab = labels.Value(i)
        counts[label_entry(lab)] = counts.get(label_entry(lab), 0) + 1
        walk(lab, 0)
    return {e: u for e, u in found.items() if counts.get(e, 0) == 1}
