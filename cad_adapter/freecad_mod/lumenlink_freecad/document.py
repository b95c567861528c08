"""A FreeCAD document as LumenLink's tree: which objects are nodes, their UUIDs, placements and meshes.

Runs inside FreeCAD (its own Python: the GUI add-on, or ``freecadcmd`` for `cad_adapter.freecad`), so it uses the
standard library and FreeCAD's modules only. It changes nothing in the document: `plan` says which UUID each node
has or would get, `stamp` writes them into the document once a push has succeeded.

What is a node (what FreeCAD shows is what is simulated):
* every visible shape object (``Part::Feature`` and what derives from it: a PartDesign Body, a primitive, a
  boolean's result), App::Part and group containers, and App::Link instances;
* not a shape consumed by another through a link property (a boolean's inputs, a Pad's sketch, a Body's features),
  not a 2-D object (a sketch), not a hidden object (Visibility off) nor anything inside a hidden container.

Identity lives in the document: each node object carries ``LumenLinkUUID`` and ``LumenLinkOwner`` (the object's
internal ``Name``, which FreeCAD never reuses while the object exists). A copy made in FreeCAD carries its
original's properties under a new Name, so it gets a new UUID; Undo restores an object with its properties, so its
UUID comes back. Nodes inside an App::Link to a container (one link, many objects) get UUIDs derived from the link's
and the object's path (uuid5), as do the elements of a link array.

Geometry: each distinct shape (an object and every link to it) is meshed once in its own frame by FreeCAD's mesher
(``MeshPart.meshFromShape``: BRepMesh at a linear deflection in mm and an angular one in radians), then read face
by face, so each triangle keeps its B-rep face and each vertex the face's own normal; the node's transform is its
Placement, local to its container.
"""

from __future__ import annotations

import base64
import re
import sys
import uuid
from array import array

import FreeCAD as App
import MeshPart

PROP_UUID = "LumenLinkUUID"
PROP_OWNER = "LumenLinkOwner"
GROUP = "LumenLink"
FORMAT = "lumenlink-freecad-1"
CONTAINERS = ("App::Part", "App::DocumentObjectGroup")
#: link properties that attach an object to another without consuming it
ATTACHMENT = ("Support", "AttachmentSupport", "ExpressionEngine")
UUID_RE = re.compile(r"^[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}$")
LINK_TYPES = ("App::PropertyLink", "App::PropertyLinkList", "App::PropertyLinkSub", "App::PropertyLinkSubList",
              "App::PropertyLinkChild", "App::PropertyLinkListChild", "App::PropertyLinkGlobal",
              "App::PropertyLinkSubGlobal", "App::PropertyLinkListGlobal", "App::PropertyLinkSubListGlobal")


def is_container(obj) -> bool:
    return any(obj.isDerivedFrom(t) for t in CONTAINERS)


def is_link(obj) -> bool:
    return obj.isDerivedFrom("App::Link")


def is_shape(obj) -> bool:
    return obj.isDerivedFrom("Part::Feature") and not obj.isDerivedFrom("Part::Part2DObject")


def _linked(user, obj) -> bool:
    """Whether ``user`` holds ``obj`` in one of its link properties other than an attachment."""
    for prop in user.PropertiesList:
        if prop in ATTACHMENT or user.getTypeIdOfProperty(prop) not in LINK_TYPES:
            continue
        value = user.getPropertyByName(prop)
        items = value if isinstance(value, (list, tuple)) else [value]
        for item in items:
            target = item[0] if isinstance(item, tuple) else item
            if target == obj:
                return True
    return False


def container_of(obj):
    """The App::Part or group whose Group holds ``obj``, or None."""
    for user in obj.InList:
        if is_container(user) and obj in user.Group:
            return user
    return None


def consumed(obj) -> bool:
    """Whether another shape uses ``obj`` as an input (a boolean, a Pad, a Body holding its features)."""
    for user in obj.InList:
        if is_link(user) or (is_container(user) and obj in user.Group):
            continue
        if user.isDerivedFrom("Part::Feature") and _linked(user, obj):
            return True
    return False


def is_node(obj) -> bool:
    if not (is_container(obj) or is_link(obj) or is_shape(obj)):
        return False
    return bool(getattr(obj, "Visibility", True)) and not consumed(obj)


def matrix(placement) -> list[float]:
    """A Placement as 16 numbers, row-major (mm)."""
    return [float(x) for x in placement.toMatrix().A]


def _child_nodes(obj) -> list:
    return [c for c in obj.Group if is_node(c)] if is_container(obj) else []


class Plan:
    """The document's nodes, parents first: each a dict ``{uuid, parent, name, object, transform, part, issued}``
    (``object``: the FreeCAD object's Name the UUID lives on, None for a derived UUID; ``part``: the key of the
    shape it shows, None for a container; ``issued``: a new UUID the document does not hold yet), and ``shapes``:
    part key -> (label, the shape object)."""

    def __init__(self, doc) -> None:
        self.doc = doc
        self.nodes: list[dict] = []
        self.shapes: dict[str, tuple[str, object]] = {}
        self.warnings: list[str] = []
        self._seen: set[str] = set()
        for obj in doc.Objects:
            if is_node(obj) and container_of(obj) is None:
                self._add(obj, None)

    def _own_uuid(self, obj) -> tuple[str, bool]:
        value = str(getattr(obj, PROP_UUID, "") or "")
        owner = str(getattr(obj, PROP_OWNER, "") or "")
        if UUID_RE.match(value) and owner == obj.Name and value not in self._seen:
            return value, False
        return str(uuid.uuid4()), True

    def _add(self, obj, parent: str | None, derived_from: str | None = None, path: str = "") -> None:
        if derived_from is None:
            node_uuid, issued = self._own_uuid(obj)
        else:
            node_uuid, issued = str(uuid.uuid5(uuid.UUID(derived_from), path)), False
        self._seen.add(node_uuid)
        node = {"uuid": node_uuid, "parent": parent, "name": obj.Label,
                "object": obj.Name if derived_from is None else None, "transform": matrix(obj.Placement),
                "part": None, "issued": issued}
        self.nodes.append(node)
        if is_link(obj):
            self._add_link(obj, node, derived_from, path)
        elif is_container(obj):
            for child in _child_nodes(obj):
                self._add(child, node_uuid, derived_from, f"{path}/{child.Name}")
        else:
            node["part"] = self._part(obj)

    def _add_link(self, link, node: dict, derived_from: str | None, path: str) -> None:
        target = link.getLinkedObject(True)
        if target is None or target == link:
            self.warnings.append(f"{link.Label}: the link points at nothing; pushed as an empty node")
            return
        if getattr(link, "LinkTransform", False):
            node["transform"] = matrix(link.Placement.multiply(target.Placement))
        base = derived_from or node["uuid"]
        count = int(getattr(link, "ElementCount", 0) or 0)
        if count > 0:   # a link array: one child per element, each with its own placement
            for i, placement in enumerate(list(link.PlacementList)[:count]):
                child = {"uuid": str(uuid.uuid5(uuid.UUID(base), f"{path}#{i}")), "parent": node["uuid"],
                         "name": f"{link.Label}[{i}]", "object": None, "transform": matrix(placement),
                         "part": None, "issued": False}
                self.nodes.append(child)
                self._link_target(target, child, base, f"{path}#{i}")
            return
        self._link_target(target, node, base, path)

    def _link_target(self, target, node: dict, base: str, path: str) -> None:
        if is_container(target):
            for child in _child_nodes(target):
                self._add(child, node["uuid"], base, f"{path}/{child.Name}")
        elif is_shape(target):
            node["part"] = self._part(target)
        else:
            self.warnings.append(f"{node['name']}: links to {target.TypeId}, which has no shape")

    def _part(self, obj) -> str:
        self.shapes.setdefault(obj.Name, (obj.Label, obj))
        return obj.Name


def _b64(kind: str, values) -> str:
    data = array(kind, values)
    if sys.byteorder != "little":
        data.byteswap()
    return base64.b64encode(data.tobytes()).decode("ascii")


def _snap(x: float) -> float:
    """``x`` on a 1e-9 grid, -0.0 as 0.0: a recompute that rebuilds the same B-rep leaves noise of ~1e-17 (and signed
    zeros) in a few coordinates, which the geometry id's float32 would keep: a part that did not change would."""
    return round(x, 9) + 0.0


def mesh(obj, linear: float, angular: float) -> dict:
    """The shape of ``obj`` meshed in its own frame: ``{vertices, normals, triangles, face_ids}`` (base64 of
    little-endian float64, float64, uint32, uint32), ``{"empty": why}`` for a shape without faces, or
    ``{"error": why}`` where FreeCAD cannot mesh it."""
    try:
        shape = obj.Shape.copy()
        shape.Placement = App.Placement()
        if shape.isNull() or not shape.Faces:
            return {"empty": f"{obj.Label} ({obj.TypeId}) has no faces"}
        MeshPart.meshFromShape(Shape=shape, LinearDeflection=linear, AngularDeflection=angular, Relative=False)
        vertices: list[float] = []
        normals: list[float] = []
        triangles: list[int] = []
        faces: list[int] = []
        for index, face in enumerate(shape.Faces):
            points, facets = face.tessellate(linear)
            base = len(vertices) // 3
            for p in points:
                vertices += (_snap(p.x), _snap(p.y), _snap(p.z))
                n = face.normalAt(*face.Surface.parameter(p))
                normals += (_snap(n.x), _snap(n.y), _snap(n.z))
            for a, b, c in facets:
                triangles += (base + a, base + b, base + c)
                faces.append(index)
        if not triangles:
            return {"error": f"{obj.Label}: FreeCAD's mesher gave no triangles at a deflection of {linear} mm, "
                             f"{angular} rad"}
    except Exception as exc:   # FreeCAD raises Part.OCCError, RuntimeError, ... on a broken shape
        return {"error": f"{obj.Label}: FreeCAD cannot mesh this shape ({type(exc).__name__}: {exc})"}
    return {"vertices": _b64("d", vertices), "normals": _b64("d", normals), "triangles": _b64("I", triangles),
            "face_ids": _b64("I", faces)}


def export(doc, linear: float, angular: float) -> dict:
    """The document's tree and meshes (format ``lumenlink-freecad-1``), UUIDs as `Plan` gives them."""
    plan = Plan(doc)
    parts = {key: {"name": label, **mesh(obj, linear, angular)} for key, (label, obj) in plan.shapes.items()}
    return {"format": FORMAT, "name": doc.Label, "file": doc.FileName, "freecad": ".".join(App.Version()[:3]),
            "length_unit": "mm", "tessellation": {"linear": linear, "angular": angular},
            "nodes": plan.nodes, "parts": parts, "warnings": plan.warnings}


def stamp(doc, uuids: dict[str, str]) -> int:
    """Write ``{object Name: UUID}`` into the document's objects (properties ``LumenLinkUUID`` and
    ``LumenLinkOwner``, read-only in the property editor); returns how many objects changed."""
    changed = 0
    for name, value in uuids.items():
        obj = doc.getObject(name)
        if obj is None or not UUID_RE.match(value):
            continue
        for prop in (PROP_UUID, PROP_OWNER):
            if prop not in obj.PropertiesList:
                obj.addProperty("App::PropertyString", prop, GROUP, "LumenLink's identity of this node")
                obj.setEditorMode(prop, 1)
        if getattr(obj, PROP_UUID) != value or getattr(obj, PROP_OWNER) != obj.Name:
            setattr(obj, PROP_UUID, value)
            setattr(obj, PROP_OWNER, obj.Name)
            changed += 1
    return changed
