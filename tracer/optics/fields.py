"""A light's or a sensor's body fields, typed: each kind declares them once, in its ``FIELDS``.

The kind validates a body by them (its ``Spec.from_body``, with the bounds read from here), and the service
builds its wire models from them (`service.kind_wire`): the OpenAPI schema, the 422s, how an attached body
follows its node and what the tracer receives all read the same table, so a new kind needs nothing in the
service. A field's ``value`` says what it holds:

=========  ==========================================================================================
value      what it holds
=========  ==========================================================================================
point      3 finite numbers, m: a place; moves and turns with the node the body is attached to
direction  3 finite numbers, not all zero (any length; dimensionless): turns with the node, made unit
vector     3 finite numbers, m: an edge; turns with the node, its length kept
number     a finite number within ``lo`` .. ``hi`` (``lo_open``, ``hi_open``: the ends excluded)
count      an integer within ``lo`` .. ``hi``
choice     one of ``choices``
text       a string of 1 to ``max_length`` characters
node       a node of the service's scene (UUID or path) whose surfaces, its descendants' with them, the
           body covers; the tracer receives ``instances``, the ids of their instances
part_dir   3 finite numbers, not all zero: a direction in each covered part's own frame (as an element's
           ``facing``); it does not turn with an attachment, the parts carry it
faces      a non-empty list of B-rep face indices (ints, 0 to 2^24 − 1) of each covered part's mesh (as an
           element's ``faces``; the CAD adapter sends each triangle's face); the parts carry it too
=========  ==========================================================================================

``doc`` states the meaning with its unit (shown by the API docs); ``required`` fields have no default (an
optional one is absent or null, and the kind says what it then takes).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

VALUES = ("point", "direction", "vector", "number", "count", "choice", "text", "node", "part_dir", "faces")
PLACED = ("point", "direction", "vector")   # values that follow the node a body is attached to


@dataclass(frozen=True)
class BodyField:
    """One field of a light or sensor body (see the module docstring)."""

    name: str
    value: str
    doc: str
    required: bool = True
    lo: float = -math.inf
    hi: float = math.inf
    lo_open: bool = False
    hi_open: bool = False
    choices: tuple[str, ...] = ()
    max_length: int = 0

    def __post_init__(self) -> None:
        if self.value not in VALUES:
            raise ValueError(f"field {self.name!r}: value {self.value!r} is not one of {VALUES}")

    def limits(self) -> dict[str, Any]:
        """``lo``, ``hi``, ``lo_open`` as the kinds' number checks take them."""
        return {"lo": self.lo, "hi": self.hi, "lo_open": self.lo_open}


def fields(*declared: BodyField) -> dict[str, BodyField]:
    """A kind's ``FIELDS``: its body fields by name, in declaration order."""
    return {f.name: f for f in declared}


def is_placed(table: dict[str, BodyField]) -> bool:
    """Whether a body of these fields lies somewhere (a point, a direction or an edge): it may be attached to a
    node and then follows it."""
    return any(f.value in PLACED for f in table.values())


def node_field(table: dict[str, BodyField]) -> str | None:
    """The name of the field that names a node (its instances go to the tracer as ``instances``), or None."""
    return next((f.name for f in table.values() if f.value == "node"), None)
