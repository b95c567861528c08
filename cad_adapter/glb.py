"""GLB (glTF 2.0 binary) encoding of one geometry, exactly round-tripping through trimesh.

One mesh, one primitive: POSITION float32, NORMAL float32 when the mesh has normals, indices uint32.
Decoding is the wire format's one decoder, `lumenlink.glb.decode_glb`, which the service uses too to check
an upload against its id; :func:`decode_glb` here only turns its errors into the adapter's, and the tests
check that the id survives.
"""

from __future__ import annotations

import numpy as np
import trimesh

from lumenlink import glb as lumenlink_glb
from tracer.geometry_id import canonical_arrays

from .errors import CadAdapterError

MEDIA_TYPE = lumenlink_glb.MEDIA_TYPE


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

    The service's decoder (`lumenlink.glb.decode_glb`); the arrays are exactly those :func:`encode_glb` was given.
    CadAdapterError where the bytes are not a geometry GLB.
    """
    try:
        return lumenlink_glb.decode_glb(data)
    except lumenlink_glb.GlbError as exc:
        raise CadAdapterError(f"not a readable GLB: {exc}") from exc
