"""A stand-in for `tracer.Scene` that records the calls the apply step makes (for pure tests)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class FakeStats:
    blas_built: int
    blas_loaded: int
    blas_seconds: float = 0.0
    tlas_seconds: float = 0.0


class FakeScene:
    """Instances as a dict id -> (geometry id, 4x4); counts every top- and bottom-level operation."""

    def __init__(self) -> None:
        self.geoms: set[str] = set()
        self.pending: set[str] = set()
        self.inst: dict[int, tuple[str, np.ndarray]] = {}
        self.next_id = 0
        self.calls = {"add_instance": 0, "remove_instance": 0, "set_transform": 0, "add_geometry": 0}

    def add_geometry(self, vertices, triangles, normals=None, *, known_id=None, face_ids=None) -> str:
        from tracer.geometry_id import geometry_id

        gid = known_id if known_id is not None else geometry_id(vertices, triangles, normals, face_ids)
        self.calls["add_geometry"] += 1
        if gid not in self.geoms:
            self.pending.add(gid)
        self.geoms.add(gid)
        return gid

    def known(self, gid: str) -> None:
        """Register a geometry id without arrays (pure tests use made-up ids)."""
        self.geoms.add(gid)

    def add_instance(self, gid: str, transform) -> int:
        assert gid in self.geoms, f"instance of unknown geometry {gid}"
        i = self.next_id
        self.next_id += 1
        self.inst[i] = (gid, np.array(transform, dtype=float))
        self.calls["add_instance"] += 1
        return i

    def set_transform(self, i: int, transform) -> None:
        assert i in self.inst
        self.inst[i] = (self.inst[i][0], np.array(transform, dtype=float))
        self.calls["set_transform"] += 1

    def remove_instance(self, i: int) -> None:
        del self.inst[i]
        self.calls["remove_instance"] += 1

    def commit(self) -> FakeStats:
        built = len(self.pending)
        self.pending.clear()
        return FakeStats(built, 0)
