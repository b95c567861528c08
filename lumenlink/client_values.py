"""Values a `lumenlink.Client` call takes, checked before anything is sent: points and directions as [x, y, z]."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from lumenlink.errors import LumenLinkError


def triples(values: Any, what: str) -> list[list[float]]:
    """`values` as a list of [x, y, z]; a flat list, or anything else, is a usage error that says the form."""
    example = f"{what}=[[0.0, 0.0, 1.0], [0.5, 0.0, 1.0]]"
    if hasattr(values, "tolist"):
        values = values.tolist()
    if not isinstance(values, Sequence) or isinstance(values, str | bytes):
        raise LumenLinkError(f"{what} must be a list of [x, y, z] triples (metres), e.g. {example}", usage=True)
    if values and all(isinstance(v, int | float) and not isinstance(v, bool) for v in values):
        hint = (f" (group the {len(values)} numbers in threes)" if len(values) % 3 == 0 else "")
        raise LumenLinkError(f"{what} must be a list of [x, y, z] triples, e.g. {example}; got a flat list of "
                             f"{len(values)} numbers{hint}", usage=True)
    out = []
    for i, v in enumerate(values):
        if (not isinstance(v, Sequence) or isinstance(v, str | bytes) or len(v) != 3
                or not all(isinstance(c, int | float) and not isinstance(c, bool) and math.isfinite(c) for c in v)):
            raise LumenLinkError(f"{what}[{i}] must be [x, y, z] (three finite numbers), got {v!r}; e.g. {example}",
                                 usage=True)
        out.append([float(c) for c in v])
    return out
