"""Counting geometry-id hashes in a test (docs/DESIGN.md "Geometry identity": a pushed mesh is hashed once on each
side); shared by tests/service/test_hash_once.py and tests/cad_adapter/test_cad_client.py."""

from __future__ import annotations

import types

import tracer.geometry_id as ids


def counted_geometry_hashes(monkeypatch) -> list[int]:
    """Count every geometry-id hash from now on (each `tracer.geometry_id.hash_canonical`, whoever calls it):
    a counting wrapper around the SHA-256 that module starts with its prefix."""
    calls: list[int] = []
    real = ids.hashlib.sha256

    def sha256(data: bytes = b"", **kwargs):
        if data == ids.PREFIX:
            calls.append(1)
        return real(data, **kwargs)

    monkeypatch.setattr(ids, "hashlib", types.SimpleNamespace(sha256=sha256))
    return calls
