"""tracer: two-level ray tracing (per-object bottom levels, a top level over instances) in numba.

Public API (DESIGN.md): :class:`Scene`, :class:`UpdateStats`, :class:`Hits`, :class:`TracerError`,
and the module :mod:`tracer.geometry_id` (the content hash). Jitted kernels for light transport live
in :mod:`tracer.traverse` and :mod:`tracer.spawn` (docs/CONTRACTS.md).

The names are loaded on first use (PEP 562), so ``import tracer.geometry_id`` (the CAD adapter's only
need: a SHA-256 over numpy arrays) does not load numba and the kernels.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from tracer.errors import TracerError
    from tracer.scene import Hits, Scene, UpdateStats

_WHERE = {"TracerError": "tracer.errors", "Hits": "tracer.scene", "Scene": "tracer.scene",
          "UpdateStats": "tracer.scene"}

__all__ = ["Hits", "Scene", "TracerError", "UpdateStats"]


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        return getattr(importlib.import_module(_WHERE[name]), name)
    raise AttributeError(f"module 'tracer' has no attribute {name!r}")
