"""The one GLB decoder of the wire format: a pushed mesh (``PUT /geometries/{gid}``) back to its arrays.

A geometry GLB (glTF 2.0 binary) holds one mesh with one primitive: POSITION float32, NORMAL float32 where
the mesh has normals, indices (`cad_adapter.glb.encode_glb` writes it). Both sides decode with
:func:`decode_glb`: the service when it checks an upload against its id, the adapter (and its tests) when
they check that an id survives the round trip. It reads the GLB's header and JSON chunk itself (version,
length, exactly one primitive, whether it carries NORMAL) and the arrays through trimesh's public API
(``trimesh.load(..., process=False)``), and answers the canonical arrays the geometry id hashes
(`tracer.geometry_id.canonical_arrays`). Anything else raises `GlbError` (a ValueError) saying what is wrong;
each side turns it into its own error (the service: 422). Imports nothing of ours but `tracer.geometry_id`
(no numba), so the service and the adapter may both use it (tests/test_layout.py).

B-rep face indices (which face of the part each triangle tessellates, `cad_adapter.tessellate`) travel as the vertex
attribute ``_FEATURE_ID_0`` (float32, the feature-id attribute of glTF's EXT_mesh_features): the adapter's faces are
not welded, so each vertex belongs to one face and a triangle's face is its vertices' (`decode_glb_faces`; all three
must agree). A GLB without it is a mesh without face indices, as before they existed.
"""

from __future__ import annotations

import io
import json
import struct

import numpy as np

from tracer.geometry_id import canonical_arrays, canonical_faces

MEDIA_TYPE = "model/gltf-binary"
_JSON_CHUNK = 0x4E4F534A
FACE_ATTRIBUTE = "_FEATURE_ID_0"


class GlbError(ValueError):
    """The bytes are not a geometry GLB (not glTF 2 binary, not exactly one triangle mesh, bad arrays)."""


def _attributes(data: bytes) -> dict:
    """The attributes of the GLB's one mesh primitive (read from its JSON chunk)."""
    if len(data) < 20 or data[:4] != b"glTF":
        raise GlbError("the body is not a GLB file (it must start with the magic 'glTF')")
    version, length = struct.unpack_from("<II", data, 4)
    if version != 2:
        raise GlbError(f"only glTF 2 binaries (GLB version 2) are accepted, got version {version}")
    if length != len(data):
        raise GlbError(f"GLB header says {length} bytes but the body has {len(data)}")
    chunk_length, chunk_type = struct.unpack_from("<II", data, 12)
    if chunk_type != _JSON_CHUNK or 20 + chunk_length > len(data):
        raise GlbError("GLB has no valid JSON chunk")
    try:
        gltf = json.loads(data[20:20 + chunk_length])
        prims = [p for m in gltf.get("meshes", []) for p in m.get("primitives", [])]
        attributes = prims[0].get("attributes") or {} if len(prims) == 1 else {}
    except (ValueError, AttributeError, TypeError) as exc:
        raise GlbError(f"GLB JSON chunk is unreadable: {exc}") from exc
    if len(prims) != 1:
        raise GlbError(f"a geometry must be exactly one mesh primitive; the GLB has {len(prims)}")
    return dict(attributes)


def decode_glb(data: bytes) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Decode a geometry GLB into its canonical arrays.

    Parameters
    ----------
    data : bytes
        A GLB holding one triangle mesh primitive.

    Returns
    -------
    vertices : (n, 3) float32
    triangles : (m, 3) uint32, m >= 1
    normals : (n, 3) float32, or None where the GLB has no NORMAL attribute

    Raises
    ------
    GlbError
        Not a glTF 2 binary, not exactly one triangle mesh, no triangles, or arrays that
        `canonical_arrays` refuses (shapes, non-finite values, indices out of range).
    """
    v, f, n, _ = decode_glb_faces(data)
    return v, f, n


def decode_glb_faces(data: bytes) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]:
    """`decode_glb` and the mesh's B-rep face indices: uint32 (m,), one per triangle, or None where the GLB carries
    no ``_FEATURE_ID_0``. `GlbError` also where a triangle's vertices name different faces."""
    attributes = _attributes(data)
    has_normals = "NORMAL" in attributes
    import trimesh  # on first decode: neither side pays for it at start-up

    try:
        loaded = trimesh.load(io.BytesIO(data), file_type="glb", process=False)
    except Exception as exc:  # trimesh raises many kinds on bad input
        raise GlbError(f"GLB could not be decoded: {type(exc).__name__}: {exc}") from exc
    meshes = list(loaded.geometry.values()) if isinstance(loaded, trimesh.Scene) else [loaded]
    if len(meshes) != 1:
        raise GlbError(f"a geometry must be exactly one mesh; the GLB holds {len(meshes)}")
    mesh = meshes[0]
    if not isinstance(mesh, trimesh.Trimesh):
        raise GlbError(f"the GLB holds a {type(mesh).__name__}, not a triangle mesh")
    # the normals the file carries: trimesh keeps them as loaded (process=False), it computes none here
    normals = np.asarray(mesh.vertex_normals) if has_normals else None
    try:
        v, f, n = canonical_arrays(np.asarray(mesh.vertices), np.asarray(mesh.faces), normals)
    except ValueError as exc:
        raise GlbError(f"invalid mesh: {exc}") from exc
    if len(f) == 0:
        raise GlbError("invalid mesh: it has no triangles")
    faces = None
    if FACE_ATTRIBUTE in attributes:
        per_vertex = np.asarray(getattr(mesh, "vertex_attributes", {}).get(FACE_ATTRIBUTE, np.zeros(0)))
        per_vertex = per_vertex.reshape(len(per_vertex), -1)[:, 0] if per_vertex.ndim > 1 else per_vertex
        if per_vertex.shape != (len(v),):
            raise GlbError(f"{FACE_ATTRIBUTE} must give one B-rep face index per vertex ({len(v)}), got "
                           f"{per_vertex.shape}")
        corners = per_vertex[f.astype(np.int64)]
        if not (corners[:, 0] == corners[:, 1]).all() or not (corners[:, 0] == corners[:, 2]).all():
            bad = int(np.flatnonzero((corners[:, 0] != corners[:, 1]) | (corners[:, 0] != corners[:, 2]))[0])
            raise GlbError(f"{FACE_ATTRIBUTE}: triangle {bad}'s vertices name different B-rep faces "
                           f"{corners[bad].tolist()}: a face index is one per triangle")
        try:
            faces = canonical_faces(corners[:, 0], len(f))
        except ValueError as exc:
            raise GlbError(f"{FACE_ATTRIBUTE}: {exc}") from exc
    return v, f, n, faces
