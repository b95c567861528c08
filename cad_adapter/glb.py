"""GLB (glTF 2.0 binary) encoding of one geometry, exactly round-tripping through trimesh.

One mesh, one primitive: POSITION float32, NORMAL float32 when the mesh has normals, indices uint32.
The service decodes with ``trimesh.load(..., process=False)`` and recomputes the geometry id from the
decoded arrays; :func:`decode_glb` does the same here, and the tests check that the id survives.
"""

from __future__ import annotations

import io

import numpy as np
import trimesh

from tracer.geometry_id import canonical_arrays

from .errors import CadAdapterError

MEDIA_TYPE = "model/gltf-binary"


def encode_glb(vertices: np.ndarray, triangles: np.ndarray, normals: np.ndarray | None = None) -> bytes:
    """Encode a mesh as GLB bytes.

    Parameters
    ----------
    vertices : (n, 3) float
        Cast to float32 exactly as the geometry id hashes them.
    triangles : (m, 3) int
    normals : (n, 3) float, optional

    Raises
    ------
    CadAdapterError
        Bad shapes or values (from ``tracer.geometry_id.canonical_arrays``), or an empty mesh.
    """
    try:
        v, f, n = canonical_arrays(vertices, triangles, normals)
    except ValueError as exc:
        raise CadAdapterError(f"cannot encode mesh: {exc}") from exc
    if len(f) == 0:
        raise CadAdapterError("cannot encode an empty mesh (no triangles)")
    kwargs = {"vertex_normals": n} if n is not None else {}
    mesh = trimesh.Trimesh(vertices=v, faces=f, process=False, validate=False, **kwargs)
    # unitize_normals=False: trimesh would otherwise renormalise and move some normals by an ulp
    data = mesh.export(file_type="glb", include_normals=n is not None, unitize_normals=False)
    return bytes(data)


def decode_glb(data: bytes) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Decode GLB bytes into (vertices float32 (n,3), triangles uint32 (m,3), normals float32 or None).

    Mirrors what the service does (``trimesh.load(..., process=False)``); the arrays are exactly those
    :func:`encode_glb` was given.
    """
    try:
        loaded = trimesh.load(io.BytesIO(data), file_type="glb", process=False)
    except Exception as exc:
        raise CadAdapterError(f"not a readable GLB: {exc}") from exc
    meshes = list(loaded.geometry.values()) if isinstance(loaded, trimesh.Scene) else [loaded]
    if len(meshes) != 1 or not isinstance(meshes[0], trimesh.Trimesh):
        raise CadAdapterError(f"a geometry GLB holds exactly one triangle mesh, this one holds {len(meshes)} item(s)")
    mesh = meshes[0]
    normals = np.asarray(mesh.vertex_normals) if "vertex_normals" in mesh._cache.cache else None
    return canonical_arrays(mesh.vertices, mesh.faces, normals)
