"""A pushed mesh is hashed once on the service's side (docs/DESIGN.md "Geometry identity"): when its upload is checked
against the id in the URL; never again to build its bottom level, on a push, or when a restarted service loads
the scene back."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from service_helpers import car_document, grid_mesh, make_client

import tracer.geometry_id as ids
from tests.hash_counting import counted_geometry_hashes


def with_normals(n: int, z: float) -> tuple[str, bytes]:
    """A mesh as the adapter uploads it: vertex normals in the GLB and in its id."""
    v, f = grid_mesh(n, z=z)
    normals = np.tile([0.0, 0.0, 1.0], (len(v), 1))
    data = trimesh.Trimesh(v, f, vertex_normals=normals, process=False).export(
        file_type="glb", include_normals=True, unitize_normals=False)
    return ids.geometry_id(v, f, normals), data


def without_normals(n: int, z: float) -> tuple[str, bytes]:
    v, f = grid_mesh(n, z=z)
    return ids.geometry_id(v, f), trimesh.Trimesh(v, f, process=False).export(file_type="glb")


def test_each_pushed_mesh_is_hashed_once(tmp_path, monkeypatch) -> None:
    meshes = [with_normals(2, 0.0), without_normals(3, 1.0)]
    hashes = counted_geometry_hashes(monkeypatch)
    with make_client(tmp_path) as client:
        for gid, data in meshes:
            r = client.put(f"/geometries/{gid}", content=data)
            assert r.status_code == 201, r.text
        assert len(hashes) == 2                          # the upload's check, one per mesh
        assert client.get(f"/geometries/{meshes[0][0]}").status_code == 200
        sid = client.post("/scenes", json={"name": "car"}).json()["id"]
        doc = car_document(meshes[0][0], meshes[1][0])   # six instances of the two meshes
        answer = client.put(f"/scenes/{sid}/document", json=doc)
        assert answer.status_code == 200, answer.text
        assert answer.json()["blas_built"] == 2
        moved = car_document(meshes[0][0], meshes[1][0], base_revision=1, door_x=50.0)
        assert client.put(f"/scenes/{sid}/document", json=moved).status_code == 200
        assert len(hashes) == 2                          # building both bottom levels and two pushes: none
    with make_client(tmp_path) as client:                # a restart loads the scene and its meshes back
        assert client.get(f"/scenes/{sid}").json()["objects"] == 6
        assert len(hashes) == 2
    # and the check still holds: a mesh whose id is not its hash is refused
    gid, data = meshes[0]
    with make_client(tmp_path / "other") as client:
        wrong = client.put(f"/geometries/{'0' * 64}", content=data)
        assert wrong.status_code == 400 and wrong.headers["content-type"].startswith("application/problem+json")
        assert wrong.json()["actual"] != "0" * 64


def test_a_known_id_must_be_a_geometry_id() -> None:
    """`tracer.Scene.add_geometry(..., known_id=)` takes the id as given (no hash) but never a malformed one: the
    id names the bottom level's file in a BLAS library."""
    import tracer

    v, f = grid_mesh(1)
    scene = tracer.Scene()
    gid = ids.geometry_id(v, f)
    assert scene.add_geometry(v, f, known_id=gid) == gid == scene.add_geometry(v, f)
    with pytest.raises(tracer.TracerError, match="known_id"):
        scene.add_geometry(v, f, known_id="../../etc/passwd")
