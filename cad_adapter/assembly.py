"""Reading an in-memory ``cadquery.Assembly`` into a :class:`~cad_adapter.tree.Document`.

Each assembly object is one node: its ``loc`` is the transform local to its parent, its ``obj`` (if any)
the part it shows. Objects sharing the same shapes (the same Workplane or Shape added several times)
are one part, so a wheel added four times is one geometry and four nodes. A node's
``metadata["uuid"]`` (or ``metadata["lumenlink_uuid"]``) is a UUID the document carries. Lengths are in
the assembly's unit, millimetres by cadquery's convention unless told otherwise.
"""

from __future__ import annotations

import cadquery as cq
from OCP.BRep import BRep_Builder
from OCP.TopoDS import TopoDS_Compound

from .errors import CadImportError, EmptyDocumentError
from .step_reader import location_matrix
from .tessellate import has_faces
from .tree import UNIT_METRES, Document, Node, Part, assign_paths

UUID_KEYS = ("uuid", "lumenlink_uuid")


def _color(a: cq.Assembly) -> tuple[float, float, float] | None:
    if a.color is None:
        return None
    r, g, b, _ = a.color.toTuple()
    return (float(r), float(g), float(b))


def _shape(shapes: list) -> object:
    if len(shapes) == 1:
        return shapes[0].wrapped
    comp = TopoDS_Compound()
    builder = BRep_Builder()
    builder.MakeCompound(comp)
    for s in shapes:
        builder.Add(comp, s.wrapped)
    return comp


def read_assembly(assy: cq.Assembly, length_unit: str = "mm", name: str | None = None) -> Document:
    """Turn a cadquery assembly into a :class:`Document` (paths assigned; UUIDs not yet).

    Parameters
    ----------
    assy : cadquery.Assembly
    length_unit : str
        Unit of the assembly's lengths (a key of ``tree.UNIT_METRES``).
    name : str, optional
        Document name; default the root's name.

    Raises
    ------
    CadImportError
        Not an assembly, or an unknown unit.
    EmptyDocumentError
        No object with faces anywhere in the assembly.
    """
    if not isinstance(assy, cq.Assembly):
        raise CadImportError(f"expected a cadquery.Assembly, got {type(assy).__name__}")
    if length_unit not in UNIT_METRES:
        raise CadImportError(f"unknown length unit {length_unit!r}; use one of {sorted(UNIT_METRES)}")
    doc = Document(name=name or assy.name, length_unit=length_unit, nodes=[], parts={})
    keys: dict[tuple[int, ...], str] = {}

    def walk(a: cq.Assembly, parent: int | None, inherited) -> None:
        carried = next((str(a.metadata[k]) for k in UUID_KEYS if a.metadata and a.metadata.get(k)), None)
        color = _color(a) or inherited
        part = None
        shapes = a.shapes if a.obj is not None else []
        if shapes:
            sig = tuple(hash(s.wrapped) for s in shapes)
            part = keys.get(sig)
            if part is None:
                part = f"cq:{len(keys)}"
                keys[sig] = part
                doc.parts[part] = Part(key=part, name=a.name, shape=_shape(shapes), color=color)
        node = Node(index=len(doc.nodes), name=str(a.name)[:500], parent=parent,
                    transform=location_matrix(a.loc.wrapped),
                    part=part, color=color, carried_uuid=carried, product=str(a.name)[:500])
        doc.nodes.append(node)
        for child in a.children:
            walk(child, node.index, color)

    walk(assy, None, None)
    if not any(has_faces(p.shape) for p in doc.parts.values()):
        raise EmptyDocumentError(f"assembly {assy.name!r} holds no shape with faces")
    assign_paths(doc)
    return doc
