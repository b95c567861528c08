"""Each request body is validated once: FastAPI validates an assignment's body against its wire model, and the
domain code takes that model as it is, without running every validator again (issue 35)."""

from __future__ import annotations

import pytest
from service_helpers import car_document, glb, grid_mesh, make_client, uid

import service.optics
import tracer.optics.lights.dispatch
import tracer.optics.lights.goniometric

IES = """IESNA:LM-63-2002
TILT=NONE
1 -1 1 3 1 1 2 0 0 0
1 1 0
0 45 90
0
1000 800 0
"""


@pytest.fixture
def scene(tmp_path):
    meshes = [glb(*grid_mesh(2)), glb(*grid_mesh(3, z=1.0))]
    with make_client(tmp_path) as client:
        for gid, data in meshes:
            assert client.put(f"/geometries/{gid}", content=data).status_code == 201
        sid = client.post("/scenes", json={"name": "car"}).json()["id"]
        assert client.put(f"/scenes/{sid}/document", json=car_document(meshes[0][0], meshes[1][0])).status_code == 200
        yield client, sid


def counted(monkeypatch, module, name: str) -> list[int]:
    calls: list[int] = []
    real = getattr(module, name)

    def wrapper(*args, **kwargs):
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(module, name, wrapper)
    return calls


def test_a_material_body_is_validated_once(scene, monkeypatch) -> None:
    """A material's model validator asks the tracer (`material_spec`) once per validation."""
    client, sid = scene
    checks = counted(monkeypatch, service.optics, "material_spec")
    r = client.put(f"/scenes/{sid}/materials/{uid(1)}", json={"type": "dielectric", "ior": 1.5})
    assert r.status_code == 200, r.text
    assert r.json()["material"]["ior"] == 1.5
    assert len(checks) == 1
    bad = client.put(f"/scenes/{sid}/materials/{uid(1)}", json={"type": "lambertian", "reflectance": 1.5})
    assert bad.status_code == 422 and bad.headers["content-type"].startswith("application/problem+json")
    assert client.get(f"/scenes/{sid}/materials").json()[0]["material"]["type"] == "dielectric"   # unchanged


def test_a_light_body_is_validated_once(scene, monkeypatch) -> None:
    """A goniometric light's model validator asks the tracer (`light_spec`: its axes, and its file parsed) once;
    nothing parses the file again when it is added."""
    client, sid = scene
    checks = counted(monkeypatch, tracer.optics.lights.dispatch, "light_spec")
    parses = counted(monkeypatch, tracer.optics.lights.goniometric, "parse_photometry")
    body = {"type": "goniometric", "position": [0, 0, 2], "format": "ies", "data": IES,
            "direction": [0, 0, -1], "c0": [1, 0, 0]}
    r = client.post(f"/scenes/{sid}/lights", json=body)
    assert r.status_code == 201, r.text
    assert r.json()["body"]["c0"] == [1.0, 0.0, 0.0]
    assert len(checks) == 1 and len(parses) == 1
    bad = client.post(f"/scenes/{sid}/lights", json={**body, "c0": [0, 0, -2]})   # parallel to direction
    assert bad.status_code == 422 and "parallel" in bad.text
    assert len(client.get(f"/scenes/{sid}/lights").json()) == 1   # the bad one changed nothing
