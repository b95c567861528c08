"""tracer: two-level ray tracing (per-object bottom levels, a top level over instances) in numba.

Public API (DESIGN.md): :class:`Scene`, :class:`UpdateStats`, :class:`Hits`, :class:`TracerError`,
:func:`geometry_id`. Jitted kernels for light transport live in :mod:`tracer.traverse` and
:mod:`tracer.spawn` (docs/CONTRACTS.md).
"""

from tracer.errors import TracerError
from tracer.geometry_id import geometry_id
from tracer.scene import Hits, Scene, UpdateStats

__all__ = ["Hits", "Scene", "TracerError", "UpdateStats", "geometry_id"]
