"""Content-addressed mesh files: GLB upload, validation against the geometry id, fast reload.

An uploaded mesh is kept twice under ``<data_dir>/meshes/``: the GLB exactly as received
(``<gid>.glb``, served back by ``GET /geometries/{gid}``) and its canonical arrays
(``<gid>.npz``: float32 vertices, uint32 triangles, optional float32 normals, optional uint32 B-rep face indices,
one per triangle, where the adapter sent them: `lumenlink.glb`) that the service
loads into `tracer.Scene` without decoding glTF again. File names are built only from ids that
passed `tracer.geometry_id.is_geometry_id` (64 lowercase hex characters), so no path can escape
the directory. Files are written to a temporary name and renamed: a reader never sees half a file.
"""

from __future__ import annotations

import io
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lumenlink import glb
from service.errors import BadRequest, Invalid, NotFound
from tracer.geometry_id import hash_canonical, is_geometry_id


@dataclass
class Mesh:
    """Canonical arrays of one geometry: (n,3) float32, (m,3) uint32, (n,3) float32 or None, and each triangle's
    B-rep face index (m,) uint32 or None."""

    vertices: np.ndarray
    triangles: np.ndarray
    normals: np.ndarray | None
    face_ids: np.ndarray | None = None


def check_id(gid: str) -> str:
    """`gid` if it is a geometry id (64 lowercase hex characters), else Invalid (422)."""
    if not is_geometry_id(gid):
        shown = gid if len(gid) <= 80 else gid[:80] + "…"
        raise Invalid(f"geometry id must be 64 lowercase hex characters (a SHA-256), got {shown!r}")
    return gid


def decode_glb(data: bytes) -> Mesh:
    """Decode a one-mesh GLB into canonical arrays (`lumenlink.glb.decode_glb`, the one decoder both sides use);
    Invalid (422) for anything that is not a valid mesh."""
    try:
        v, f, n, faces = glb.decode_glb_faces(data)
    except glb.GlbError as exc:
        raise Invalid(str(exc)) from exc
    return Mesh(v, f, n, faces)


class MeshStore:
    """The mesh files under one directory (content-addressed by geometry id)."""

    def __init__(self, root: Path) -> None:
        self.root = Path(root)
        self.root.mkdir(parents=True, exist_ok=True)

    def _path(self, gid: str, suffix: str) -> Path:
        return self.root / f"{check_id(gid)}{suffix}"

    def has(self, gid: str) -> bool:
        return self._path(gid, ".npz").exists()

    def validate_upload(self, gid: str, data: bytes) -> Mesh:
        """Decode `data` and check that it hashes to `gid`: BadRequest (400) if not, Invalid (422) if no mesh.

        The id is computed as the mesh comes (with its normals where it has them): one hash for a right id.
        Only where that is not `gid` and the mesh has normals is the id without them tried (a client that
        hashes its positions only); the mesh is then kept without normals. The stored arrays are not hashed
        again (`Scenes.ensure_geometry` gives the tracer their id)."""
        check_id(gid)
        mesh = decode_glb(data)
        full = hash_canonical(mesh.vertices, mesh.triangles, mesh.normals, mesh.face_ids)
        if full == gid:
            return mesh
        if mesh.normals is None:
            raise BadRequest(f"the mesh does not hash to the id in the URL: it hashes to {full}", actual=full)
        plain = hash_canonical(mesh.vertices, mesh.triangles, None, mesh.face_ids)
        if plain == gid:
            return Mesh(mesh.vertices, mesh.triangles, None, mesh.face_ids)
        raise BadRequest(f"the mesh does not hash to the id in the URL: it hashes to {full} (with its normals), "
                         f"{plain} (without)", actual=plain)

    def write(self, gid: str, data: bytes, mesh: Mesh) -> None:
        """Store the GLB and its arrays (atomically; rewriting an existing id is harmless)."""
        buf = io.BytesIO()
        arrays = {"vertices": mesh.vertices, "triangles": mesh.triangles}
        if mesh.normals is not None:
            arrays["normals"] = mesh.normals
        if mesh.face_ids is not None:
            arrays["face_ids"] = mesh.face_ids
        np.savez(buf, **arrays)  # type: ignore[arg-type]
        self._atomic_write(self._path(gid, ".glb"), data)
        self._atomic_write(self._path(gid, ".npz"), buf.getvalue())

    def _atomic_write(self, path: Path, data: bytes) -> None:
        fd, tmp = tempfile.mkstemp(dir=self.root, prefix=".tmp-")
        try:
            with os.fdopen(fd, "wb") as fh:
                fh.write(data)
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise

    def glb(self, gid: str) -> bytes:
        path = self._path(gid, ".glb")
        if not path.exists():
            raise NotFound(f"no geometry {gid}")
        return path.read_bytes()

    def load(self, gid: str) -> Mesh:
        """The canonical arrays of a stored mesh (NotFound if it was never uploaded)."""
        path = self._path(gid, ".npz")
        if not path.exists():
            raise NotFound(f"no geometry {gid}")
        with np.load(path) as z:
            normals = z["normals"] if "normals" in z.files else None
            faces = z["face_ids"] if "face_ids" in z.files else None
            return Mesh(z["vertices"], z["triangles"], normals, faces)
