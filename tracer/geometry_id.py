"""Geometry identity: the content hash of a tessellation (docs/DESIGN.md, "Geometry identity").

The id is the lowercase hex SHA-256 of ``b"lumenlink-mesh-v1\\0"``, ``struct.pack("<II", n, m)``,
the vertices as little-endian float32 (n×3, C order), the triangle indices as little-endian
uint32 (m×3), only where the mesh has vertex normals, the normals as little-endian float32 and, only where it
carries B-rep face indices (the adapter's, one per triangle), ``b"faces\\0"`` then those indices as little-endian
uint32 (m). A mesh without face indices hashes as before they existed. The same tessellation gives the same id in
the adapter, the service and the tracer.
"""

from __future__ import annotations

import hashlib
import re
import struct

import numpy as np

PREFIX = b"lumenlink-mesh-v1\0"
GEOMETRY_ID = re.compile(r"^[0-9a-f]{64}$")


def canonical_arrays(
    vertices: np.ndarray, triangles: np.ndarray, normals: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """The arrays exactly as hashed: float32 (n,3), uint32 (m,3), float32 (n,3) or None.

    Raises ValueError on wrong shapes, non-finite values, negative or out-of-range indices.
    """
    v = np.asarray(vertices)
    f = np.asarray(triangles)
    if v.ndim != 2 or v.shape[1] != 3:
        raise ValueError(f"vertices must have shape (n, 3), got {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3:
        raise ValueError(f"triangles must have shape (m, 3), got {f.shape}")
    if not np.issubdtype(v.dtype, np.number) or np.issubdtype(v.dtype, np.complexfloating):
        raise ValueError(f"vertices must be real numbers, got dtype {v.dtype}")
    if f.size and not np.issubdtype(f.dtype, np.integer):
        raise ValueError(f"triangle indices must be integers, got dtype {f.dtype}")
    with np.errstate(over="ignore", invalid="ignore"):  # overflow to inf is reported below
        v32 = v.astype("<f4")
    if not np.isfinite(v32).all():
        bad = int(np.flatnonzero(~np.isfinite(v32).all(axis=1))[0])
        raise ValueError(f"vertex {bad} is not finite (as float32): {v[bad].tolist()}")
    if f.size and (f.min() < 0 or f.max() >= len(v)):
        raise ValueError(f"triangle indices must lie in [0, {len(v) - 1}], found {int(f.min())}..{int(f.max())}")
    n32 = None
    if normals is not None:
        n = np.asarray(normals)
        if n.shape != v.shape:
            raise ValueError(f"normals must have the vertices' shape {v.shape}, got {n.shape}")
        n32 = n.astype("<f4")
        if not np.isfinite(n32).all():
            raise ValueError("normals must be finite")
        n32 = np.ascontiguousarray(n32)
    return np.ascontiguousarray(v32), np.ascontiguousarray(f.astype("<u4")), n32


FACES = b"faces\0"
MAX_FACE_INDEX = 2 ** 24 - 1   # a face index travels in a GLB as float32 (`lumenlink.glb`): exact up to 2^24


def canonical_faces(face_ids: np.ndarray | None, m: int) -> np.ndarray | None:
    """B-rep face indices as hashed: uint32 (m,), one per triangle, in [0, 2^24); None stays None.

    Raises ValueError for a wrong length, non-integers or indices out of range."""
    if face_ids is None:
        return None
    a = np.asarray(face_ids)
    if a.shape != (m,):
        raise ValueError(f"face_ids must give one B-rep face index per triangle ({m}), got shape {a.shape}")
    if a.size and not np.issubdtype(a.dtype, np.integer):
        if not (np.issubdtype(a.dtype, np.floating) and np.isfinite(a).all() and (a == np.round(a)).all()):
            raise ValueError("face_ids must be integers (B-rep face indices)")
    if a.size and (a.min() < 0 or a.max() > MAX_FACE_INDEX):
        raise ValueError(f"face_ids must lie in [0, {MAX_FACE_INDEX}], found {a.min():g}..{a.max():g}")
    return np.ascontiguousarray(a.astype("<u4"))


def geometry_id(vertices: np.ndarray, triangles: np.ndarray, normals: np.ndarray | None = None,
                face_ids: np.ndarray | None = None) -> str:
    """Lowercase hex SHA-256 content hash of a mesh, as docs/DESIGN.md defines it (face indices where it has them)."""
    v, f, n = canonical_arrays(vertices, triangles, normals)
    return hash_canonical(v, f, n, canonical_faces(face_ids, len(f)))


def hash_canonical(v: np.ndarray, f: np.ndarray, n: np.ndarray | None, faces: np.ndarray | None = None) -> str:
    """The id of arrays that `canonical_arrays` (and `canonical_faces`) already returned (no second validation on a
    hot path)."""
    h = hashlib.sha256(PREFIX)
    h.update(struct.pack("<II", len(v), len(f)))
    h.update(v.tobytes())
    h.update(f.tobytes())
    if n is not None:
        h.update(n.tobytes())
    if faces is not None:
        h.update(FACES)
        h.update(faces.tobytes())
    return h.hexdigest()


def is_geometry_id(text: str) -> bool:
    """True for 64 lowercase hex characters (safe as a file name)."""
    return isinstance(text, str) and GEOMETRY_ID.fullmatch(text) is not None
