"""The stored meshes as every scene sees them: which ids are known (this process's, and those another service
process on the same database stored), uploads checked and kept once, and a mesh added to a scene's tracer scene
once. A part of `service.scenes.Scenes`, which holds ``store``, ``meshes`` and ``known_geometries``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from service.errors import NotFound, Unavailable

if TYPE_CHECKING:
    from service.meshes import MeshStore
    from service.store import SceneStore


class SceneGeometries:
    """Meshes by geometry id (see the module docstring)."""

    store: SceneStore
    meshes: MeshStore
    known_geometries: set[str]

    def _look_up_geometries(self, ids: Any) -> None:
        """Add to the known geometries those of `ids` that another service process stored (one SELECT)."""
        unknown = {g for g in ids if isinstance(g, str) and g not in self.known_geometries}
        if unknown:
            self.known_geometries.update(self.store.geometry_ids(unknown))

    def known(self, ids: list[str]) -> set[str]:
        self._look_up_geometries(ids)
        return {g for g in ids if g in self.known_geometries}

    def missing_geometries(self, ids: list[str]) -> list[str]:
        self._look_up_geometries(ids)
        seen: set[str] = set()
        out = []
        for g in ids:
            if g not in self.known_geometries and g not in seen:
                seen.add(g)
                out.append(g)
        return out

    def put_geometry(self, gid: str, data: bytes) -> dict[str, Any]:
        """Store an uploaded GLB (idempotent): 400 if it does not hash to `gid`, 422 if it is no valid mesh."""
        mesh = self.meshes.validate_upload(gid, data)
        self._look_up_geometries([gid])
        created = gid not in self.known_geometries or not self.meshes.has(gid)
        if created:
            self.meshes.write(gid, data, mesh)
            self.store.add_geometry(gid, len(mesh.vertices), len(mesh.triangles), mesh.normals is not None, len(data))
            self.known_geometries.add(gid)
        return {"id": gid, "vertices": len(mesh.vertices), "triangles": len(mesh.triangles),
                "normals": mesh.normals is not None, "faces": mesh.face_ids is not None, "bytes": len(data),
                "created": created}

    def geometry_glb(self, gid: str) -> bytes:
        self._look_up_geometries([gid])
        if gid not in self.known_geometries:
            raise NotFound(f"no geometry {gid}")
        return self.meshes.glb(gid)

    def ensure_geometry(self, state: Any, gid: str) -> bool:
        """Add a stored mesh to the scene's tracer scene (once); whether it was added now."""
        if gid in state.geometries:
            return False
        if not self.meshes.has(gid):
            # stored by another service process whose data directory this one does not share
            raise Unavailable(f"geometry {gid} is in the database but not in this process's mesh store "
                              f"({self.meshes.root}): every service process on one database must share one data "
                              f"directory (LUMENLINK_DATA_DIR)", geometry=gid)
        mesh = self.meshes.load(gid)
        # the store holds only meshes whose id was checked on upload (one hash per mesh): not hashed again here
        state.tracer.add_geometry(mesh.vertices, mesh.triangles, mesh.normals, known_id=gid, face_ids=mesh.face_ids)
        state.geometries.add(gid)
        if mesh.face_ids is not None:   # what an element assignment by B-rep `faces` selects from
            state.face_ids[gid] = mesh.face_ids
        return True
