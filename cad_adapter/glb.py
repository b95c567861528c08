"""GLB (glTF 2.0 binary) encoding of one geometry, exactly round-tripping through trimesh.

One mesh, one primitive: POSITION float32, NORMAL float32 when the mesh has normals, indices uint32.
Decoding is the wire format's one decoder, `lumenlink.glb.decode_glb`, which the service uses too to check
an upload against its id; :func:`decode_glb` here only turns its errors into the adapter's, and the tests
check that the id survives.
"""

from __future__ import annotations

import numpy as np

from lumenlink import glb as lumenlink_glb
from tracer.geometry_id import canonical_arrays, canonical_faces

from .errors import CadAdapterError

MEDIA_TYPE = lumenlink_glb.MEDIA_TYPE


def encode_glb(vertices: np.ndarray, triangles: np.ndarray, normals: np.ndarray | None = None,
               face_ids: np.ndarray | None = None) -> bytes:
    """Encode a mesh as GLB bytes (with its B-rep face indices, where given, as ``_FEATURE_ID_0``).

    Parameters
    ----------
    vertices : (n, 3) float
        Cast to float32 exactly as the geometry id hashes them.
    triangles : (m, 3) int
    normals : (n, 3) float, optional
    face_ids : (m,) int, optional
        Each triangle's B-rep face index; a vertex must belong to the triangles of one face (the adapter's faces
        are not welded).

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
    kwargs: dict = {"vertex_normals": n} if n is not None else {}
    if face_ids is not None:
        try:
            faces = canonical_faces(face_ids, len(f))
        except ValueError as exc:
            raise CadAdapterError(f"cannot encode mesh: {exc}") from exc
        assert faces is not None
        per_vertex = np.zeros(len(v), np.float32)
        per_vertex[f.ravel()] = np.repeat(faces, 3)
        if not (per_vertex[f] == faces[:, None]).all():
            raise CadAdapterError("cannot encode mesh: a vertex is shared by triangles of different B-rep faces "
                                  "(face indices travel per vertex: give each face its own vertices)")
        kwargs["vertex_attributes"] = {lumenlink_glb.FACE_ATTRIBUTE: per_vertex}
    import trimesh  # on the first upload: a push that uploads nothing does not pay for it

    mesh = trimesh.Trimesh(vertices=v, faces=f, process=False, validate=False, **kwargs)
    # unitize_normals=False: trimesh would otherwise renormalise and move some normals by an ulp
    data = mesh.export(file_type="glb", include_normals=n is not None, unitize_normals=False)
    return bytes(data)  # type: ignore[arg-type]  (a GLB export is bytes)


def decode_glb_faces(data: bytes) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]:
    """`decode_glb` and the mesh's B-rep face indices (uint32 (m,) or None): ``geometry_id(*decode_glb_faces(b))`` is
    the id the mesh was pushed under."""
    try:
        return lumenlink_glb.decode_glb_faces(data)
    except lumenlink_glb.GlbError as exc:
        raise CadAdapterError(f"not a readable GLB: {exc}") from exc


def decode_glb(data: bytes) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Decode GLB bytes into (vertices float32 (n,3), triangles uint32 (m,3), normals float32 or None).

    The service's decoder (`lumenlink.glb.decode_glb`); the arrays are exactly those :func:`encode_glb` was given.
    CadAdapterError where the bytes are not a geometry GLB.
    """
    try:
        return lumenlink_glb.decode_glb(data)
    except lumenlink_glb.GlbError as exc:
        raise CadAdapterError(f"not a readable GLB: {exc}") from exc
