"""Builders shared by the service tests: meshes as GLB, documents, a TestClient on a temp data dir."""

from __future__ import annotations

import uuid as uuidlib
from pathlib import Path
from typing import Any

import numpy as np
import trimesh

from tracer.geometry_id import geometry_id

IDENTITY = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]


def grid_mesh(n: int = 2, z: float = 0.0, size: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """A flat n×n-cell square (2n² triangles) in the plane z, side `size`: vertices (k,3), triangles (m,3)."""
    xs = np.linspace(0.0, size, n + 1)
    gx, gy = np.meshgrid(xs, xs, indexing="ij")
    v = np.column_stack([gx.ravel(), gy.ravel(), np.full(gx.size, z)])
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    f = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    return v, f


def glb(vertices: np.ndarray, triangles: np.ndarray) -> tuple[str, bytes]:
    """(geometry id, GLB bytes) of a mesh, encoded the way the adapter does (trimesh, no processing)."""
    data = trimesh.Trimesh(vertices, triangles, process=False).export(file_type="glb")
    return geometry_id(vertices, triangles), data


def uid(i: int) -> str:
    return str(uuidlib.UUID(int=0xABC000 + i))


def translation(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> list[float]:
    t = list(IDENTITY)
    t[3], t[7], t[11] = x, y, z
    return t


def node(u: str, parent: str | None, name: str, transform: list[float] | None = None,
         geometry: str | None = None, **extra: Any) -> dict[str, Any]:
    out = {"uuid": u, "parent": parent, "name": name, "transform": transform or list(IDENTITY),
           "geometry": geometry}
    out.update(extra)
    return out


def car_document(gid_body: str, gid_wheel: str, base_revision: int | None = 0, door_x: float = 0.0,
                 unit: str = "mm") -> dict[str, Any]:
    """root → body (mesh), door (mesh, hinged at door_x), axle → 4 wheels (one mesh, four instances)."""
    nodes = [node(uid(0), None, "car"),
             node(uid(1), uid(0), "body", geometry=gid_body),
             node(uid(2), uid(0), "door", translation(door_x, 0, 0), geometry=gid_body),
             node(uid(3), uid(0), "axle", translation(0, 0, 100))]
    nodes += [node(uid(10 + k), uid(3), f"wheel{k}", translation(100 * k, 0, 0), geometry=gid_wheel)
              for k in range(4)]
    return {"base_revision": base_revision, "length_unit": unit,
            "source": {"name": "car.step", "tessellation": {"linear": 0.1, "angular": 0.5}}, "nodes": nodes}


UNKNOWN_ID = "00000000-0000-4000-8000-00000000dead"   # a well-formed id no scene, node, light or sensor has


def make_client(data_dir: Path, **settings: Any):
    """A TestClient on a fresh app whose data live in `data_dir` (real tracer, real SQLite file)."""
    from fastapi.testclient import TestClient

    from service.app import create_app
    from service.config import Settings

    app = create_app(Settings(data_dir=data_dir, log_requests=False, **settings))
    return TestClient(app, raise_server_exceptions=False)


def raw_glb(positions: np.ndarray, indices: np.ndarray) -> bytes:
    """A one-primitive GLB written by hand, so tests can make meshes no encoder would (bad indices)."""
    import json
    import struct

    pos = np.ascontiguousarray(positions, dtype="<f4")
    idx = np.ascontiguousarray(indices, dtype="<u4").ravel()
    binary = pos.tobytes() + idx.tobytes()
    binary += b"\0" * (-len(binary) % 4)
    gltf = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "buffers": [{"byteLength": len(binary)}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": pos.nbytes},
                        {"buffer": 0, "byteOffset": pos.nbytes, "byteLength": idx.nbytes}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": len(pos), "type": "VEC3",
                       "min": pos.min(axis=0).tolist(), "max": pos.max(axis=0).tolist()},
                      {"bufferView": 1, "componentType": 5125, "count": len(idx), "type": "SCALAR"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "mode": 4}]}],
    }
    text = json.dumps(gltf).encode()
    text += b" " * (-len(text) % 4)
    total = 12 + 8 + len(text) + 8 + len(binary)
    return (struct.pack("<4sII", b"glTF", 2, total) + struct.pack("<II", len(text), 0x4E4F534A) + text
            + struct.pack("<II", len(binary), 0x004E4942) + binary)


def lit_floor(client: Any, side: float, reflectance: float, light: dict, name: str = "floor") -> str:
    """A scene `name` of one Lambertian floor of `reflectance`, `side` × `side` m centred on the origin in z = 0
    (node ``uid(1)``), under `light` (a light body); its id."""
    sid = client.post("/scenes", json={"name": name}).json()["id"]
    v, f = grid_mesh(n=4, size=side)
    gid, data = glb(v, f)
    assert client.put(f"/geometries/{gid}", content=data, headers={"content-type": "model/gltf-binary"}
                      ).status_code in (200, 201)
    doc = {"base_revision": 0, "length_unit": "m",
           "nodes": [node(uid(0), None, "room"), node(uid(1), uid(0), "floor", translation(-side / 2, -side / 2), gid)]}
    assert client.put(f"/scenes/{sid}/document", json=doc).status_code == 200
    assert client.put(f"/scenes/{sid}/materials/{uid(1)}", json={"type": "lambertian", "reflectance": reflectance}
                      ).status_code in (200, 201)
    assert client.post(f"/scenes/{sid}/lights", json=light).status_code == 201
    return sid

