"""What every element body's checks share: the error they raise and the checks of a number, a pair and a body's
keys, each message naming the field and what to do (the feature shapes, the micro-structure, the gratings)."""

from __future__ import annotations

import math
from typing import Any

from tracer.errors import TracerError


class ElementError(TracerError):
    """An element body that cannot be prepared; the message names the field and what to do."""


class SupportTaken(ElementError):
    """A support that shares triangles with another element of the same part (`key`: that element's key)."""

    def __init__(self, message: str, key: object) -> None:
        super().__init__(message)
        self.key = key


def number(x: Any, where: str, *, lo: float = 0.0, lo_open: bool = True, hi: float = math.inf) -> float:
    """`x` as a float in ``(lo, hi]`` (``[lo, hi]`` where not `lo_open`); `where` names the field."""
    if isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(x):
        raise ElementError(f"{where} must be a finite number, got {x!r}"[:300])
    if (x <= lo if lo_open else x < lo) or x > hi:
        bound = f"> {lo:g}" if lo_open else f">= {lo:g}"
        raise ElementError(f"{where} must be {bound}" + (f" and <= {hi:g}" if hi < math.inf else "") + f", got {x!r}")
    return float(x)


def pair(x: Any, where: str, **bounds: Any) -> tuple[float, float]:
    """Two numbers ``[u, v]`` (mm), each checked as `number` with `bounds`."""
    if not isinstance(x, list | tuple) or len(x) != 2:
        raise ElementError(f"{where} must be two numbers [u, v] in mm, got {x!r}"[:300])
    return number(x[0], f"{where}[0]", **bounds), number(x[1], f"{where}[1]", **bounds)


def check_fields(body: dict, where: str, required: set[str], optional: set[str]) -> None:
    """An element body's keys: a clear error for an unknown or a missing one."""
    unknown = sorted(set(body) - required - optional)
    if unknown:
        raise ElementError(f"{where}: unknown field(s) {unknown}; known: {sorted(required | optional)}")
    missing = sorted(required - set(body))
    if missing:
        raise ElementError(f"{where}: missing field(s) {missing}")
