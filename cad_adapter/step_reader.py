"""Reading STEP (AP203/AP214/AP242) through OCP's XCAF reader into a :class:`~cad_adapter.tree.Document`.

The walk follows XCAF's structure: free shapes are the roots; an assembly label's components are
references to other labels (assemblies or simple shapes) placed by a location. A simple shape referred
to N times becomes one :class:`~cad_adapter.tree.Part` and N nodes, so instancing survives.

Units: the file's length unit (``STEPControl_Reader.FileUnits``) is set as the XCAF document's unit
before the transfer, so OCCT does not rescale and every length stays in the file's own unit, which the
document then declares. A file without a recognised unit is read in millimetres (with a warning).

Colours, in order: the component's own colour (instance colour), the referred part's label colour, the
shape's colour, and failing those the colour covering the largest area of the part's faces.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from OCP.BRepGProp import BRepGProp
from OCP.GProp import GProp_GProps
from OCP.IFSelect import IFSelect_RetDone
from OCP.Quantity import Quantity_Color
from OCP.STEPCAFControl import STEPCAFControl_Reader
from OCP.TCollection import TCollection_ExtendedString
from OCP.TColStd import TColStd_SequenceOfAsciiString
from OCP.TDF import TDF_Label, TDF_LabelSequence
from OCP.TDocStd import TDocStd_Document
from OCP.TopAbs import TopAbs_FACE
from OCP.TopExp import TopExp_Explorer
from OCP.TopLoc import TopLoc_Location
from OCP.XCAFApp import XCAFApp_Application
from OCP.XCAFDoc import (
    XCAFDoc_ColorGen,
    XCAFDoc_ColorSurf,
    XCAFDoc_ColorTool,
    XCAFDoc_DocumentTool,
    XCAFDoc_LengthUnit,
)

from .errors import CadImportError, EmptyDocumentError
from .sides import display_name
from .tree import UNIT_METRES, Document, Node, Part, assign_paths
from .xcaf import carried_uuids, label_entry, label_name

#: STEP unit names (lower case, as ``FileUnits`` reports them) to the units a document may declare.
STEP_UNITS: dict[str, str] = {
    "millimetre": "mm", "millimeter": "mm", "mm": "mm",
    "centimetre": "cm", "centimeter": "cm", "cm": "cm",
    "metre": "m", "meter": "m", "m": "m",
    "micrometre": "um", "micrometer": "um", "micron": "um",
    "inch": "in", "in": "in",
    "foot": "ft", "feet": "ft", "ft": "ft",
}

def check_step_file(path: str | Path) -> Path:
    """Return ``path`` as a Path if it names a readable STEP Part 21 file, else raise CadImportError.

    Reading the first bytes first gives a clear message for the common mistakes (wrong path, a
    directory, a mesh or a PDF handed in by accident) instead of OCCT's bare failure status.
    """
    p = Path(path)
    if not p.exists():
        raise CadImportError(f"{p}: no such file")
    if p.is_dir():
        raise CadImportError(f"{p}: is a directory, not a STEP file")
    try:
        with p.open("rb") as fh:
            head = fh.read(256)
    except OSError as exc:
        raise CadImportError(f"{p}: cannot be read ({exc.strerror})") from exc
    if not head.strip():
        raise CadImportError(f"{p}: the file is empty")
    text = head.lstrip(b"\xef\xbb\xbf \t\r\n")
    if not text.startswith(b"ISO-10303-21"):
        raise CadImportError(
            f"{p}: not a STEP file (a STEP Part 21 file starts with 'ISO-10303-21;', this one with "
            f"{text[:24]!r})"
        )
    return p


def location_matrix(loc: TopLoc_Location) -> np.ndarray:
    """A TopLoc_Location as a (4, 4) float64 matrix (homogeneous, row-major)."""
    trsf = loc.Transformation()
    m = np.eye(4)
    for r in range(3):
        for c in range(4):
            m[r, c] = trsf.Value(r + 1, c + 1)
    return m


def _rgb(col: Quantity_Color) -> tuple[float, float, float]:
    return (float(col.Red()), float(col.Green()), float(col.Blue()))


def _label_color(label: TDF_Label) -> tuple[float, float, float] | None:
    col = Quantity_Color()
    for kind in (XCAFDoc_ColorSurf, XCAFDoc_ColorGen):
        if XCAFDoc_ColorTool.GetColor_s(label, kind, col):
            return _rgb(col)
    return None


def _shape_color(shape, color_tool) -> tuple[float, float, float] | None:
    col = Quantity_Color()
    for kind in (XCAFDoc_ColorSurf, XCAFDoc_ColorGen):
        if color_tool.GetColor(shape, kind, col):
            return _rgb(col)
    return None


def _face_color(shape, color_tool) -> tuple[float, float, float] | None:
    """The face colour covering the largest area (documents that colour only faces)."""
    areas: dict[tuple[float, float, float], float] = {}
    exp = TopExp_Explorer(shape, TopAbs_FACE)
    while exp.More():
        face = exp.Current()
        rgb = _shape_color(face, color_tool)
        if rgb is not None:
            props = GProp_GProps()
            BRepGProp.SurfaceProperties_s(face, props)
            areas[rgb] = areas.get(rgb, 0.0) + abs(props.Mass())
        exp.Next()
    if not areas:
        return None
    return max(sorted(areas), key=lambda k: areas[k])


def _has_face(shape) -> bool:
    return TopExp_Explorer(shape, TopAbs_FACE).More()


class _Walker:
    """Builds nodes and parts from an XCAF document."""

    def __init__(self, doc: TDocStd_Document, name: str, unit: str, source: Path | None) -> None:
        self.shape_tool = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
        self.color_tool = XCAFDoc_DocumentTool.ColorTool_s(doc.Main())
        self.doc = Document(name=name, length_unit=unit, nodes=[], parts={}, source=source)
        self.carried: dict[str, str] = {}  # label entry -> uuid carried by the file (see read_step)

    def part(self, label: TDF_Label) -> str:
        key = label_entry(label)
        if key not in self.doc.parts:
            shape = self.shape_tool.GetShape_s(label)
            color = _label_color(label) or _shape_color(shape, self.color_tool) or _face_color(shape, self.color_tool)
            self.doc.parts[key] = Part(key=key, name=label_name(label), shape=shape, color=color)
        return key

    def add_node(self, name: str, parent: int | None, transform: np.ndarray, *, part: str | None = None,
                 color=None, carried: str | None = None, product: str = "") -> int:
        node = Node(index=len(self.doc.nodes), name=display_name(name, product)[:500], parent=parent,
                    transform=transform, part=part, color=color, carried_uuid=carried, product=product[:500])
        self.doc.nodes.append(node)
        return node.index

    def walk_root(self, label: TDF_Label) -> None:
        transform = np.eye(4)
        name = label_name(label)
        color = _label_color(label)
        carried = self.carried.get(label_entry(label))
        if self.shape_tool.IsReference_s(label):
            transform = location_matrix(self.shape_tool.GetLocation_s(label))
            ref = TDF_Label()
            self.shape_tool.GetReferredShape_s(label, ref)
            label = ref
            name = name or label_name(label)
            carried = carried or self.carried.get(label_entry(label))
        product = label_name(label)
        if self.shape_tool.IsAssembly_s(label):
            idx = self.add_node(name, None, transform, color=color, carried=carried, product=product)
            self.walk_components(label, idx, color)
        else:
            key = self.part(label)
            self.add_node(name, None, transform, part=key, color=color or self.doc.parts[key].color,
                          carried=carried, product=product)

    def walk_components(self, label: TDF_Label, parent: int, inherited) -> None:
        comps = TDF_LabelSequence()
        self.shape_tool.GetComponents_s(label, comps)
        for i in range(1, comps.Length() + 1):
            comp = comps.Value(i)
            ref = TDF_Label()
            if not self.shape_tool.GetReferredShape_s(comp, ref):
                continue
            name = label_name(comp)  # the instance's name; blank or a writer's id: the product's is shown
            product = label_name(ref)
            transform = location_matrix(self.shape_tool.GetLocation_s(comp))
            color = _label_color(comp)
            carried = self.carried.get(label_entry(comp))
            if self.shape_tool.IsAssembly_s(ref):
                idx = self.add_node(name, parent, transform, color=color, carried=carried, product=product)
                self.walk_components(ref, idx, color or inherited)
            else:
                key = self.part(ref)
                self.add_node(name, parent, transform, part=key,
                              color=color or self.doc.parts[key].color or inherited, carried=carried,
                              product=product)


def _file_unit(reader: STEPCAFControl_Reader) -> str | None:
    lengths, angles, solids = (TColStd_SequenceOfAsciiString() for _ in range(3))
    reader.ChangeReader().FileUnits(lengths, angles, solids)
    names = {str(lengths.Value(i).ToCString()).strip().lower() for i in range(1, lengths.Length() + 1)}
    units = {STEP_UNITS.get(n) for n in names}
    if len(units) == 1 and None not in units:
        return units.pop()
    return None


def read_xcaf(path: str | Path) -> tuple[TDocStd_Document, STEPCAFControl_Reader, str, list[str]]:
    """Read a STEP file into a new XCAF document, keeping the file's length unit.

    Returns
    -------
    doc : TDocStd_Document
    reader : STEPCAFControl_Reader
        Still holding the STEP model (the UUID reader looks at its entities).
    unit : str
        The document's length unit (a key of ``tree.UNIT_METRES``).
    warnings : list of str
    """
    p = check_step_file(path).resolve()  # absolute: OCCT resolves external references against it
    warnings: list[str] = []
    reader = STEPCAFControl_Reader()
    reader.SetNameMode(True)
    reader.SetColorMode(True)
    reader.SetLayerMode(True)
    reader.SetProductMetaMode(True)
    status = reader.ReadFile(str(p))
    if status != IFSelect_RetDone:
        raise CadImportError(f"{p}: OCCT could not parse this STEP file (status {int(status)})")
    if reader.NbRootsForTransfer() == 0:
        raise EmptyDocumentError(f"{p}: the STEP file holds no product or shape to read")
    unit = _file_unit(reader)
    if unit is None:
        warnings.append("the file declares no length unit this reader knows; millimetres assumed")
        unit = "mm"
    app = XCAFApp_Application.GetApplication_s()
    doc = TDocStd_Document(TCollection_ExtendedString("XmlXCAF"))
    app.InitDocument(doc)
    XCAFDoc_DocumentTool.SetLengthUnit_s(doc, UNIT_METRES[unit])
    if not reader.Transfer(doc):
        raise CadImportError(f"{p}: the STEP file was parsed but its shapes could not be transferred")
    attr = XCAFDoc_LengthUnit()
    if doc.Main().Root().FindAttribute(XCAFDoc_LengthUnit.GetID_s(), attr):
        got = attr.GetUnitValue()
        if abs(got - UNIT_METRES[unit]) > 1e-9 * UNIT_METRES[unit]:
            raise CadImportError(f"{p}: OCCT transferred in a unit of {got} m instead of the file's {unit}")
    return doc, reader, unit, warnings


def document_from_xcaf(doc: TDocStd_Document, name: str, unit: str, source: Path | None = None,
                       carried: dict[str, str] | None = None) -> Document:
    """Walk an XCAF document into a :class:`Document` (paths assigned, UUIDs not yet).

    Parameters
    ----------
    carried : dict of str to str, optional
        UUIDs the file carries, by label entry (component or free-shape label).
    """
    walker = _Walker(doc, name, unit, source)
    walker.carried = carried or {}
    labels = TDF_LabelSequence()
    walker.shape_tool.GetFreeShapes(labels)
    for i in range(1, labels.Length() + 1):
        walker.walk_root(labels.Value(i))
    out = walker.doc
    if not out.nodes:
        raise EmptyDocumentError(f"{name}: the document holds no shape")
    if not any(_has_face(p.shape) for p in out.parts.values()):
        raise EmptyDocumentError(f"{name}: the document holds no surface to tessellate "
                                 f"({len(out.nodes)} node(s), none with faces)")
    empty = sorted({p.name or p.key for p in out.parts.values() if not _has_face(p.shape)})
    if empty:
        out.warnings.append(f"{len(empty)} part(s) without faces (shown as nodes without geometry): "
                            + ", ".join(empty[:10]) + (" ..." if len(empty) > 10 else ""))
    assign_paths(out)
    return out


def read_step(path: str | Path) -> Document:
    """Read a STEP file into a :class:`~cad_adapter.tree.Document`.

    Parameters
    ----------
    path : str or pathlib.Path
        A STEP Part 21 file (AP203, AP214 or AP242). External references are resolved relative to it.

    Returns
    -------
    Document
        Nodes (parents first) with occurrence paths and any UUIDs the file carries; UUIDs are assigned
        by :func:`cad_adapter.identity.assign_uuids`.

    Raises
    ------
    CadImportError
        Missing, unreadable or non-STEP file, or OCCT fails on it.
    EmptyDocumentError
        The file holds no shape with faces.
    """
    doc, reader, unit, warnings = read_xcaf(path)
    p = Path(path).resolve()
    out = document_from_xcaf(doc, p.name, unit, p, carried_uuids(reader, doc))
    out.warnings[:0] = warnings
    return out
