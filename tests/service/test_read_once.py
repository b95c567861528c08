"""A query reads the scene's state once (issue 35): one version check against the database per simulate request,
where there were four (the sensor lookup, the scene's existence, its lock, its snapshot)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from service_helpers import glb, grid_mesh, make_client, node, translation, uid

from service.store import SceneStore


def test_a_sensor_query_reads_the_scene_s_version_once(tmp_path: Path, monkeypatch: Any) -> None:
    with make_client(tmp_path) as client:
        sid = client.post("/scenes", json={"name": "once"}).json()["id"]
        gid, data = glb(*grid_mesh(n=2, size=2.0))
        client.put(f"/geometries/{gid}", content=data, headers={"content-type": "model/gltf-binary"})
        client.put(f"/scenes/{sid}/document", json={"base_revision": 0, "length_unit": "m", "nodes": [
            node(uid(0), None, "room"), node(uid(1), uid(0), "floor", translation(-1, -1, 0), gid)]})
        client.put(f"/scenes/{sid}/materials/{uid(1)}", json={"type": "lambertian", "reflectance": 0.5})
        client.post(f"/scenes/{sid}/lights", json={"type": "point", "position": [0, 0, 1], "intensity_cd": 100})
        sensor = client.post(f"/scenes/{sid}/sensors", json={"type": "disk", "center": [0, 0, 0.001],
                                                             "normal": [0, 0, 1], "radius": 0.05}).json()["id"]
        url = f"/scenes/{sid}/sensors/{sensor}/simulate"
        assert client.post(url, json={"max_photons": 2000}).status_code == 200
        reads = []
        original = SceneStore.version

        def counted(self: SceneStore, scene_id: str) -> Any:
            reads.append(scene_id)
            return original(self, scene_id)

        monkeypatch.setattr(SceneStore, "version", counted)
        answer = client.post(url, json={"max_photons": 2000, "seed": 2})
        assert answer.status_code == 200, answer.text
        assert reads == [sid]
        missing = client.post(f"/scenes/{'0' * 8}-0000-4000-8000-{'0' * 12}/sensors/{sensor}/simulate", json={})
        assert missing.status_code == 404
