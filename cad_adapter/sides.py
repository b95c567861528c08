"""The trees identity matching compares (`cad_adapter.matching`): each side as arrays (`Side`), a part's
frame-independent invariants (`ShapeKey`), and which names are people's and which a STEP writer made up."""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

#: relative tolerance of shape classes (frame-independent invariants of one part, scaled by its size)
CLASS_RTOL = 1e-5

#: names writers generate (blank instance names, renumbered ids): never evidence, never shown to people
WRITER_ID = re.compile(r"^(?:|\d+|NAUO\d*|=>\[[0-9:]+\]|(?:SOLID|SHELL|COMPOUND|COMPONENT|PART|BODY)[_ ]?\d*|"
                       r"OPEN_CASCADE_STEP_TRANSLATO-\d+|#\d+|I\d+)$", re.IGNORECASE)


def is_writer_id(name: str | None) -> bool:
    """Whether a name is one a STEP writer made up (blank, a number, ``NAUO61``), not a person."""
    return name is None or WRITER_ID.match(name.strip()) is not None


def display_name(instance: str | None, product: str | None) -> str:
    """The name a person sees: the instance name, unless blank or a writer's id; then the product's."""
    if instance and not is_writer_id(instance):
        return instance
    if product and not is_writer_id(product):
        return product
    return instance or product or "unnamed"


@dataclass(frozen=True)
class ShapeKey:
    """Frame-independent invariants of a part: what stays when a writer moves the solid in its frame.

    Attributes
    ----------
    volume, area : float
        Document units³ and units².
    moments : tuple of 3 float
        Principal moments of inertia about the centroid (unit density), ascending, units⁵.
    topology : tuple of 3 int
        Faces, edges, vertices (0, 0, 0 where unknown).
    """

    volume: float
    area: float
    moments: tuple[float, float, float]
    topology: tuple[int, int, int] = (0, 0, 0)

    @property
    def size(self) -> float:
        """A length of the part: sqrt(area)."""
        return float(np.sqrt(max(self.area, 0.0)))

    def matches(self, other: ShapeKey, rtol: float = CLASS_RTOL) -> bool:
        """Equal within ``rtol`` of the part's size (size³ for volumes, size² for areas, size⁵ for moments)."""
        if self.topology != other.topology and 0 not in (sum(self.topology), sum(other.topology)):
            return False
        s = max(self.size, other.size)
        if s == 0.0:
            return self.volume == other.volume and self.area == other.area
        close = (abs(self.volume - other.volume) <= rtol * (abs(self.volume) + s ** 3)
                 and abs(self.area - other.area) <= rtol * (abs(self.area) + s ** 2))
        return close and all(abs(a - b) <= rtol * (abs(a) + s ** 5)
                             for a, b in zip(self.moments, other.moments, strict=True))


@dataclass
class Side:
    """One tree as matching sees it (parents before children).

    Attributes
    ----------
    parent : (n,) int64
        Parent row, -1 for a root.
    names, products : list of str
        Instance names and product names (either may be blank).
    world : (n, 4, 4) float64
        ``root_from_node``, in the new document's unit.
    local : (n, 4, 4) float64
        ``parent_from_node``, same unit.
    keys : list of ShapeKey or None
        The part's invariants; None for an assembly (or a part without faces: see ``leaf``).
    centroid : (n, 3) float64
        A leaf's centre of volume in the part's frame (its origin where unknown).
    leaf : (n,) bool
        Shows a part (possibly without faces).
    uuids : list of str or None
        Known UUIDs (old side), or carried ones (new side), else None.
    paths : list of str
    axes : (n, 3, 3) float64 or None
        A leaf's principal axes of inertia (rows) in the part's frame (zeros where unknown): one
        unambiguous part then gives the model's rotation, even when the unambiguous parts lie on a line.
    """

    parent: np.ndarray
    names: list[str]
    products: list[str]
    world: np.ndarray
    local: np.ndarray
    keys: list[ShapeKey | None]
    centroid: np.ndarray
    leaf: np.ndarray
    uuids: list[str | None]
    paths: list[str]
    axes: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.names)

    @classmethod
    def empty(cls) -> Side:
        return cls(np.zeros(0, np.int64), [], [], np.zeros((0, 4, 4)), np.zeros((0, 4, 4)), [], np.zeros((0, 3)),
                   np.zeros(0, bool), [], [])
