"""tracer: two-level ray tracing and light transport in numba (filled in by issues 3 and 6)."""

from tracer.geometry_id import geometry_id

__all__ = ["geometry_id"]
