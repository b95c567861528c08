"""The document tree the adapter builds from a CAD document, before and after identity is assigned.

Conventions
-----------
* A :class:`Part` is one distinct shape (a STEP product with geometry, a cadquery object). A part used
  five times is one :class:`Part` and five :class:`Node` objects with their own transforms.
* ``Node.transform`` is the 4×4 matrix ``parent_from_node`` (local to the parent), in document units;
  the pushed JSON flattens it row-major. Part geometry lives in the part's own frame.
* ``Node.path`` is the occurrence path: the names from the root down, joined by ``/``; among siblings
  sharing a name the first (in document order) keeps it bare, the next are ``name[2]``, ``name[3]``… (the
  service's rule, ``service.paths``). It is what a re-import is matched by when the document carries no UUID.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

#: Lengths of the units a document may declare, in metres.
UNIT_METRES: dict[str, float] = {"um": 1e-6, "mm": 1e-3, "cm": 1e-2, "m": 1.0, "in": 0.0254, "ft": 0.3048}


@dataclass
class Part:
    """One distinct shape of the document.

    Attributes
    ----------
    key : str
        Stable key inside one reading of the document (an XCAF label entry, or a cadquery shape hash).
    name : str
        The product's name.
    shape : OCP.TopoDS.TopoDS_Shape
        The B-rep in the part's own frame, document units.
    color : tuple of 3 float or None
        Representative surface colour (linear RGB in [0, 1]).
    """

    key: str
    name: str
    shape: Any
    color: tuple[float, float, float] | None = None
    _signature: Any = field(default=None, repr=False)


@dataclass
class Node:
    """One node of the tree: an assembly, a sub-assembly or an occurrence of a part.

    Attributes
    ----------
    index : int
        Position in :attr:`Document.nodes` (parents come before their children).
    name : str
        Display name (instance name, else product name).
    parent : int or None
        Index of the parent node; None for a root.
    transform : (4, 4) float64 ndarray
        ``parent_from_node``, document units.
    part : str or None
        Key of the part this node shows; None for a pure assembly node.
    color : tuple of 3 float or None
        The node's colour (instance colour, else the part's).
    path : str
        Occurrence path (see module docstring).
    carried_uuid : str or None
        UUID the document itself carries for this node (cadquery metadata, STEP attribute).
    uuid : str or None
        The node's UUID once :func:`cad_adapter.identity.assign_uuids` ran.
    match : str or None
        How the UUID was found: one of :data:`cad_adapter.matching.RULES`.
    product : str
        The product's name (what the occurrence is an instance of); '' where the document has none.
    previous : dict or None
        The old node record this node was matched to (scene or sidecar), once identity ran.
    """

    index: int
    name: str
    parent: int | None
    transform: np.ndarray
    part: str | None = None
    color: tuple[float, float, float] | None = None
    path: str = ""
    carried_uuid: str | None = None
    uuid: str | None = None
    match: str | None = None
    product: str = ""
    previous: dict | None = field(default=None, repr=False)


@dataclass
class Document:
    """A CAD document as a flat tree of nodes plus its distinct parts.

    Attributes
    ----------
    name : str
        Document name (the file name, or the root assembly's name).
    length_unit : str
        One of :data:`UNIT_METRES`' keys; every length in the tree and the parts is in this unit.
    nodes : list of Node
        Parents before children.
    parts : dict of str to Part
        Distinct shapes, by key.
    source : pathlib.Path or None
        The file read, if any (the sidecar goes next to it).
    warnings : list of str
        Things the reader noticed and worked around (empty external references, unknown units, ...).
    reuse : dict of str to str
        Part key -> geometry id kept from the scene (same B-rep within tolerance: not tessellated again).
    reuse_if_same_surface : dict of str to str
        Part key -> geometry id of the scene's mesh, for parts whose B-rep is close but not the same by its
        invariants (a writer split an edge): kept if the new mesh shows the same surface
        (:func:`cad_adapter.identity.confirm_same_surface`).
    reconciliation : dict
        How identity was found (the push's ``reconciliation``: nodes per rule, ambiguous ones).
    """

    name: str
    length_unit: str
    nodes: list[Node]
    parts: dict[str, Part]
    source: Path | None = None
    warnings: list[str] = field(default_factory=list)
    reuse: dict[str, str] = field(default_factory=dict)
    reuse_if_same_surface: dict[str, str] = field(default_factory=dict)
    reconciliation: dict = field(default_factory=dict)
    reconciliation_detail: dict = field(default_factory=dict)

    def children(self, index: int | None) -> list[Node]:
        """The nodes whose parent is ``index`` (None: the roots), in document order."""
        return [n for n in self.nodes if n.parent == index]

    def world_transform(self, index: int) -> np.ndarray:
        """``root_from_node`` (4, 4) of node ``index``: the product of the transforms up to its root."""
        m = np.eye(4)
        i: int | None = index
        while i is not None:
            node = self.nodes[i]
            m = node.transform @ m
            i = node.parent
        return m

    def leaves(self) -> list[Node]:
        """Nodes that show a part."""
        return [n for n in self.nodes if n.part is not None]

    def by_path(self) -> dict[str, Node]:
        """Nodes by occurrence path."""
        return {n.path: n for n in self.nodes}


def assign_paths(doc: Document) -> None:
    """Fill ``Node.path`` for every node: the service's rule (``service.paths``): among siblings sharing a
    name the first keeps it bare, the next get ``[2]``, ``[3]``… in document order.

    Parameters
    ----------
    doc : Document
        Modified in place; nodes must be ordered parents first.
    """
    seen: dict[tuple[int | None, str], int] = {}
    for n in doc.nodes:
        segment = n.name.replace("/", "\u2215")  # a slash inside a name must not split the path
        k = seen.get((n.parent, n.name), 0) + 1
        seen[(n.parent, n.name)] = k
        if k > 1:
            segment = f"{segment}[{k}]"
        n.path = segment if n.parent is None else f"{doc.nodes[n.parent].path}/{segment}"
