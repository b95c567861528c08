"""The geometry id is docs/DESIGN.md's hash, computed here independently from the spec's words."""

from __future__ import annotations

import hashlib
import struct

import numpy as np
import pytest

from tracer.geometry_id import geometry_id, is_geometry_id

V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=np.float64)
F = np.array([[0, 1, 2]])


def spec_hash(v, f, n=None) -> str:
    data = b"lumenlink-mesh-v1\0" + struct.pack("<II", len(v), len(f))
    data += b"".join(struct.pack("<fff", *row) for row in v)
    data += b"".join(struct.pack("<III", *row) for row in f)
    if n is not None:
        data += b"".join(struct.pack("<fff", *row) for row in n)
    return hashlib.sha256(data).hexdigest()


def test_matches_spec_without_and_with_normals() -> None:
    assert geometry_id(V, F) == spec_hash(V.tolist(), F.tolist())
    n = np.tile([0.0, 0.0, 1.0], (3, 1))
    assert geometry_id(V, F, n) == spec_hash(V.tolist(), F.tolist(), n.tolist())
    assert geometry_id(V, F, n) != geometry_id(V, F)


def test_dtype_and_layout_do_not_change_the_id() -> None:
    assert geometry_id(V.astype(np.float32), F.astype(np.int64)) == geometry_id(V, F.astype(np.uint32))
    assert geometry_id(np.asfortranarray(V), F) == geometry_id(V, F)


def test_any_change_changes_the_id() -> None:
    moved = V.copy()
    moved[2, 1] = 1.0001
    assert geometry_id(moved, F) != geometry_id(V, F)
    assert geometry_id(V, F[:, ::-1]) != geometry_id(V, F)


@pytest.mark.parametrize(
    ("v", "f", "message"),
    [
        (V[:, :2], F, "vertices must have shape"),
        (V, F[:, :2], "triangles must have shape"),
        (np.array([[0, 0, np.nan], [1, 0, 0], [0, 1, 0]]), F, "vertex 0 is not finite"),
        (np.array([[0, 0, 1e39], [1, 0, 0], [0, 1, 0]]), F, "not finite"),
        (V, np.array([[0, 1, 3]]), "indices must lie in"),
        (V, np.array([[0, -1, 2]]), "indices must lie in"),
        (V, F.astype(float), "must be integers"),
    ],
)
def test_bad_input_is_a_clear_value_error(v, f, message) -> None:
    with pytest.raises(ValueError, match=message):
        geometry_id(v, f)


def test_is_geometry_id_rejects_path_tricks() -> None:
    assert is_geometry_id(geometry_id(V, F))
    for text in ["../" + "a" * 61, "A" * 64, "a" * 63, "a" * 65, "g" * 64, ""]:
        assert not is_geometry_id(text)
