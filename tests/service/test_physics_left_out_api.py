"""Physics left out through the REST API (issue 24): ``"physics_left_out": ["polarization"]`` on a query makes the
answer carry ``physics_left_out.polarization``: the lux with polarization forced on minus the answer's, with its
standard error; bad names are a 422 naming the known effects, never a 5xx.

The scene: a lossless glass block (n = 1.5, 1 cm thick, 4 m × 4 m) under an unpolarized beam of 100 lx, radius
5 mm, at Brewster's angle; a receiver (radius 0.3 m) across the specular reflection 1 m away. Closed forms
(tests/tracer/optics/test_polarization.py): the s/p-averaged Fresnel the queries force (`force_effects_off`)
reflects 2R/(1 + R) = 0.137740 of the beam (R = Rs/2, Rs = 0.147929), polarized Fresnel Rs/(1 + Rs) = 0.128867. A
black floor under a point light (tests/service/test_simulation_api.py) is the scene where polarization changes nothing.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh
from service_helpers import make_client, node, uid
from test_simulation_api import push_floor, query

from service.meshes import decode_glb
from tracer.effects import EFFECTS
from tracer.geometry_id import geometry_id

RS = 0.147929
POLARIZED, AVERAGED = RS / (1 + RS), RS / (1 + RS / 2)
BEAM_R, RECEIVER_R = 0.005, 0.3
THETA = math.atan(1.5)
D = [math.sin(THETA), 0.0, -math.cos(THETA)]          # the beam's direction, onto z = 0 at the origin
REFLECTED = [D[0], 0.0, -D[2]]


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    client = make_client(tmp_path_factory.mktemp("left_out"), max_points=50, max_photons=4_000_000,
                         max_seconds=60.0)
    with client:
        glass = client.post("/scenes", json={"name": "plate"}).json()["id"]
        block = trimesh.creation.box(extents=[4.0, 4.0, 0.01])
        v, t = np.asarray(block.vertices) + [0, 0, -0.005], np.asarray(block.faces)
        data = trimesh.Trimesh(v, t, process=False).export(file_type="glb")
        mesh = decode_glb(data)
        gid = geometry_id(mesh.vertices, mesh.triangles)
        assert client.put(f"/geometries/{gid}", content=data,
                          headers={"content-type": "model/gltf-binary"}).status_code in (200, 201)
        doc = {"base_revision": 0, "length_unit": "m", "source": {"name": "plate"},
               "nodes": [node(uid(0), None, "bench"), node(uid(1), uid(0), "plate", geometry=gid)]}
        assert client.put(f"/scenes/{glass}/document", json=doc).status_code == 200
        r = client.put(f"/scenes/{glass}/materials/{uid(1)}", json={"type": "dielectric", "ior": 1.5})
        assert r.status_code == 200, r.text
        r = client.post(f"/scenes/{glass}/lights", json={
            "type": "collimated", "origin": [-d for d in D], "direction": D, "radius": BEAM_R, "illuminance_lx": 100.0})
        assert r.status_code == 201, r.text
        r = client.post(f"/scenes/{glass}/sensors", json={"type": "grid", "origin": [1.2, 0.5, 1.0],
                                                         "u": [1.0, 0.0, 0.0], "v": [0.0, -1.0, 0.0], "nu": 2, "nv": 2})
        assert r.status_code == 201, r.text
        floor = client.post("/scenes", json={"name": "floor"}).json()["id"]
        push_floor(client, floor, 0)
        assert client.put(f"/scenes/{floor}/materials/{uid(1)}", json={"type": "black"}).status_code == 200
        assert client.post(f"/scenes/{floor}/lights", json={"type": "point", "position": [0.0, 0.0, 2.0],
                                                            "intensity_cd": 100.0}).status_code == 201
        yield client, glass, r.json()["id"], floor


def test_polarization_left_out_at_brewster_is_the_closed_form_difference(world):
    client, glass, _, _ = world
    body = query([REFLECTED], [[-c for c in REFLECTED]], radius=RECEIVER_R, max_photons=400_000, seed=5,
                 physics_left_out=["polarization"], force_effects_off=["polarization"])
    r = client.post(f"/scenes/{glass}/illuminance", json=body)
    assert r.status_code == 200, r.text
    a = r.json()
    assert "polarization" not in a["effects"]
    e = a["physics_left_out"]["polarization"]
    assert e["ran"] is True and e["estimator"] == "forward" and e["photons"] > 0 and e["seconds"] > 0
    to_fraction = RECEIVER_R ** 2 / (100.0 * BEAM_R ** 2)
    diff, err = e["difference"][0] * to_fraction, e["stderr"][0] * to_fraction
    assert abs(diff - (POLARIZED - AVERAGED)) <= 4 * err, (diff, err, POLARIZED - AVERAGED)
    assert abs(diff) > 4 * err
    assert abs(a["lux"][0] * to_fraction - AVERAGED) <= 4 * a["stderr"][0] * to_fraction


def test_a_sensor_simulation_and_the_plan_carry_it_per_cell(world):
    client, glass, sensor, _ = world
    r = client.post(f"/scenes/{glass}/sensors/{sensor}/simulate",
                    json={"max_photons": 40_000, "physics_left_out": ["polarization", "fresnel"],
                          "force_effects_off": ["polarization"]})
    assert r.status_code == 200, r.text
    left = r.json()["physics_left_out"]
    assert np.shape(left["polarization"]["difference"]) == (2, 2) == np.shape(left["polarization"]["stderr"])
    assert r.json()["lux"][0][0] > 0      # the reflected beam crosses cell (0, 0), from below: the front side
    assert left["polarization"]["ran"] and left["polarization"]["stderr"][0][0] > 0
    fresnel = {k: v for k, v in left["fresnel"].items() if v is not None}     # the estimator: null, no run
    assert fresnel == {"difference": [[0.0, 0.0], [0.0, 0.0]], "stderr": [[0.0, 0.0], [0.0, 0.0]],
                       "photons": 0, "seconds": 0.0, "ran": False}   # already on: nothing runs
    r = client.post(f"/scenes/{glass}/illuminance/plan",
                    json=query([REFLECTED], [[-c for c in REFLECTED]], max_photons=20_000,
                               physics_left_out=["polarization"], force_effects_off=["polarization"]))
    assert r.status_code == 200 and r.json()["physics_left_out"]["polarization"]["ran"], r.text


def test_polarization_changes_nothing_on_a_black_floor_under_a_point_light(world):
    client, _, _, floor = world
    r = client.post(f"/scenes/{floor}/illuminance",
                    json=query([[0.0, 0.0, 0.0], [1.0, 0.5, 0.0]], radius=0.05, target_relative_error=0.01,
                               max_seconds=30.0, seed=2, physics_left_out=["polarization"]))
    assert r.status_code == 200, r.text
    a = r.json()
    e = a["physics_left_out"]["polarization"]
    assert e["ran"] and all(abs(d) <= 4 * s for d, s in zip(e["difference"], e["stderr"], strict=True)), e
    plain = client.post(f"/scenes/{floor}/illuminance", json=query([[0.0, 0.0, 0.0]], max_photons=20_000)).json()
    assert "physics_left_out" not in plain


@pytest.mark.parametrize(("extra", "match"), [
    ({"physics_left_out": ["warp_drive"]}, "known: "),
    ({"physics_left_out": ["polarization", "polarization"]}, "once"),
    ({"physics_left_out": "polarization"}, "physics_left_out"),
    ({"physics_left_out": ["Polarization!"]}, "physics_left_out"),
    ({"physics_left_out": [None]}, "physics_left_out"),
])
def test_bad_physics_left_out_is_a_422(world, extra, match):
    client, glass, sensor, _ = world
    for url, body in ((f"/scenes/{glass}/illuminance", query([[0.0, 0.0, 1.0]], max_photons=1000, **extra)),
                      (f"/scenes/{glass}/illuminance?mode=async", query([[0.0, 0.0, 1.0]], max_photons=1000, **extra)),
                      (f"/scenes/{glass}/sensors/{sensor}/simulate", {"max_photons": 1000, **extra})):
        r = client.post(url, json=body)
        assert r.status_code == 422 and match in r.text, (url, r.status_code, r.text)
        if match == "known: ":
            assert all(name in r.text for name in EFFECTS)


def test_polarization_is_on_by_default_and_the_answer_says_why(world):
    """Issue 38: the plate calls for polarization by physics; the answer reflects Rs/(1 + Rs) and names why."""
    client, glass, _, floor = world
    body = query([REFLECTED], [[-c for c in REFLECTED]], radius=RECEIVER_R, max_photons=200_000, seed=6)
    a = client.post(f"/scenes/{glass}/illuminance", json=body).json()
    assert "polarization" in a["effects"] and a["effect_reasons"]["polarization"].startswith("on: a path can meet")
    to_fraction = RECEIVER_R ** 2 / (100.0 * BEAM_R ** 2)
    assert abs(a["lux"][0] * to_fraction - POLARIZED) <= 4 * a["stderr"][0] * to_fraction
    assert set(a["effect_reasons"]) == set(EFFECTS)
    assert "polarization" in client.get(f"/scenes/{glass}").json()["effects"]   # the scene's summary, same rule
    plain = client.post(f"/scenes/{floor}/illuminance",
                        json=query([[0.0, 0.0, 0.0]], max_photons=2000, force_effects_off=["polarization"])).json()
    assert plain["effect_reasons"]["polarization"].startswith("off: no material polarizes")


@pytest.mark.parametrize(("extra", "match"), [
    ({"force_effects_off": ["fresnel"]}, "cannot be forced off"),
    ({"force_effects_off": ["warp_drive"]}, "known: "),
    ({"force_effects_off": "polarization"}, "force_effects_off"),
    ({"force_effects_off": ["polarization", "polarization"]}, "once"),
    ({"force_effects_off": ["polarization"], "observe": ["stokes"]}, "also forced on"),
    ({"force_effects_off": ["polarization"], "force_effects": ["polarization"]}, "also forced on"),
])
def test_bad_force_effects_off_is_a_422_naming_it(world, extra, match):
    client, glass, sensor, _ = world
    for url, body in ((f"/scenes/{glass}/illuminance", query([[0.0, 0.0, 1.0]], max_photons=1000, **extra)),
                      (f"/scenes/{glass}/illuminance?mode=async", query([[0.0, 0.0, 1.0]], max_photons=1000, **extra)),
                      (f"/scenes/{glass}/sensors/{sensor}/simulate", {"max_photons": 1000, **extra})):
        r = client.post(url, json=body)
        assert r.status_code == 422 and match in r.text and "force_effects_off" in r.text, (url, r.status_code,
                                                                                            r.text)


def test_the_client_and_the_cli_pass_force_effects_off_and_show_the_reasons(world, monkeypatch, tmp_path):
    """Issue 38 through `lumenlink.Client` and `lumenlink simulate`: `force_effects_off` reaches the service, the
    answer's `effect_reasons` come back (client) and are printed (CLI); a name it cannot force off exits 2."""
    from typer.testing import CliRunner

    import lumenlink.commands_results as commands_results
    from lumenlink import Client
    from lumenlink.cli import app

    client, glass, sensor, _ = world

    def on_app(server: str = "") -> Client:
        return Client("http://testserver", transport=client._transport)

    with on_app() as ll:
        a = ll.illuminance(glass, [REFLECTED], [[-c for c in REFLECTED]], max_photons=2000,
                           force_effects_off=["polarization"])
        assert "polarization" not in a["effects"]
        assert a["effect_reasons"]["polarization"].startswith("off: forced off by the query")
        [res] = ll.simulate(glass, sensor, max_photons=2000, force_effects_off=["polarization"]).values()
        assert res["effect_reasons"]["polarization"].startswith("off: forced off by the query")
        [res] = ll.simulate(glass, sensor, max_photons=2000).values()
        assert res["effect_reasons"]["polarization"].startswith("on: a path can meet")
    monkeypatch.setattr(commands_results, "Client", on_app)
    runner = CliRunner()
    r = runner.invoke(app, ["simulate", "--scene", glass, "--sensor", sensor, "--out", str(tmp_path / "a"),
                            "--max-photons", "2000", "--force-effects-off", "polarization"])
    assert r.exit_code == 0, r.output
    assert "effect polarization: off: forced off by the query" in r.output
    r = runner.invoke(app, ["simulate", "--scene", glass, "--sensor", sensor, "--out", str(tmp_path / "b"),
                            "--max-photons", "2000"])
    assert r.exit_code == 0 and "effect polarization: on: a path can meet" in r.output, r.output
    r = runner.invoke(app, ["simulate", "--scene", glass, "--sensor", sensor, "--out", str(tmp_path / "c"),
                            "--max-photons", "2000", "--force-effects-off", "fresnel"])
    assert r.exit_code == 2 and "force_effects_off" in r.output, r.output
