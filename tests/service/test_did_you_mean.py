"""A misspelt body field (issue 22): the 422 names the field and the closest allowed one ("did you mean"), also
inside a discriminated union (a light's, a material's type) and for a query's options; the request changes
nothing."""

from __future__ import annotations

import pytest
from service_helpers import make_client

from service.errors import fields_at
from service.schemas import Light


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    with make_client(tmp_path_factory.mktemp("dym")) as c:
        yield c


@pytest.mark.parametrize(("method", "path", "body", "field", "meant"), [
    ("post", "lights", {"type": "point", "position": [0, 0, 1], "intesity_cd": 5}, "body.point.intesity_cd",
     "intensity_cd"),
    ("put", "materials/car%2Flens", {"type": "mirror", "reflectanse": 0.5}, "body.mirror.reflectanse", "reflectance"),
    ("post", "sensors", {"type": "grid", "origin": [0, 0, 0], "u": [1, 0, 0], "v": [0, 1, 0], "nu": 2, "nvv": 2},
     "body.grid.nvv", "nv"),
    ("post", "illuminance", {"points": [[0, 0, 1]], "normals": [[0, 0, 1]], "max_photon": 5}, "body.max_photon",
     "max_photons"),
])
def test_a_misspelt_field_gets_did_you_mean(client, method, path, body, field, meant) -> None:
    sid = client.post("/scenes", json={"name": f"s-{field}"}).json()["id"]
    r = getattr(client, method)(f"/scenes/{sid}/{path}", json=body)
    assert r.status_code == 422, r.text
    p = r.json()
    name = field.rsplit(".", 1)[1]
    assert f"{field}: '{name}' is not a field here; did you mean '{meant}'?" in p["detail"]
    assert p["did_you_mean"] == [meant]
    (e,) = [e for e in p["errors"] if e["type"] == "extra_forbidden"]
    assert e["did_you_mean"] == meant
    # the field the typo stands for is not reported missing besides
    assert not any(e["type"] == "missing" and e["loc"][-1] == meant for e in p["errors"])
    assert client.get(f"/scenes/{sid}/lights").json() == [] and client.get(f"/scenes/{sid}/sensors").json() == []


def test_a_field_like_none_lists_the_allowed_ones(client) -> None:
    sid = client.post("/scenes", json={"name": "far"}).json()["id"]
    r = client.put(f"/scenes/{sid}/materials/x", json={"type": "mirror", "reflectance": 0.5, "zzz": 1})
    assert r.status_code == 422 and "did_you_mean" not in r.json()
    assert "'zzz' is not a field here; allowed: " in r.json()["detail"] and "reflectance" in r.json()["detail"]


def test_fields_at_walks_models_lists_and_tagged_unions() -> None:
    assert "intensity_cd" in fields_at(Light, ["point"])
    assert fields_at(Light, ["no-such-type"]) == [] and fields_at(int, []) == []
