"""Optical elements with an inside through the REST API (issue 36): the library, an edge-lit light guide whose
dots let the light out, taking them off again, a restart, and the 422s that change nothing."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from service_helpers import glb, make_client, node, uid

from tests.tracer.elements.test_mesh_feature import pyramid_mesh, upside_down
from tests.tracer.transport_scenes import box

DOTS = {"type": "microstructure", "feature": {"shape": "dome", "radius_mm": 0.3, "height_mm": 0.15},
        "layout": {"type": "grid", "pitch_mm": [1.0, 1.0]}}
PMMA = {"type": "dielectric", "ior": 1.49}
MESH = pyramid_mesh(0.6, 0.2)
# world metres: a beam into the guide's left edge, rising 0.3 per unit of x (trapped by total internal reflection),
# and a grid over the middle of its top face, front side down
BEAM = {"type": "collimated", "origin": [-0.002, 0.02, 0.001], "direction": [1.0, 0.0, 0.3], "radius": 0.0005,
        "illuminance_lx": 1e6}
ABOVE = {"type": "grid", "origin": [0.005, 0.005, 0.005], "u": [0.0, 0.03, 0.0], "v": [0.05, 0.0, 0.0], "nu": 2,
         "nv": 3}


@pytest.fixture
def client(tmp_path: Path) -> Any:
    with make_client(tmp_path) as c:
        yield c


def _guide(client: Any, steps: bool = False, name: str = "guide") -> str:
    """A 60 x 40 x 3 mm PMMA light guide (document in mm) lit at its left edge; with `steps`, a second part whose
    upward faces lie in two planes."""
    sid = client.post("/scenes", json={"name": name}).json()["id"]
    v, t = box([0, 0, 0], [60, 40, 3])
    gid, data = glb(v.astype(np.float32), t)
    assert client.put(f"/geometries/{gid}", content=data, headers={"content-type": "model/gltf-binary"}
                      ).status_code in (200, 201)
    nodes = [node(uid(0), None, "backlight"), node(uid(1), uid(0), "guide", geometry=gid)]
    if steps:
        v1, t1 = box([0, 0, 0], [10, 10, 1])
        v2, t2 = box([10, 0, 0], [20, 10, 2])
        sv, st = np.vstack([v1, v2]), np.vstack([t1, t2 + 8])
        sgid, sdata = glb(sv.astype(np.float32), st)
        client.put(f"/geometries/{sgid}", content=sdata, headers={"content-type": "model/gltf-binary"})
        nodes.append(node(uid(2), uid(0), "steps", geometry=sgid))
    r = client.put(f"/scenes/{sid}/document", json={"base_revision": 0, "length_unit": "mm", "nodes": nodes})
    assert r.status_code == 200, r.text
    assert client.put(f"/scenes/{sid}/materials/{uid(1)}", json=PMMA).status_code in (200, 201)
    assert client.post(f"/scenes/{sid}/lights", json=BEAM).status_code == 201
    return sid


def _above(client: Any, sid: str, sensor: str, seed: int = 4) -> dict:
    r = client.post(f"/scenes/{sid}/sensors/{sensor}/simulate", json={"max_photons": 60_000, "seed": seed,
                                                                        "estimator": "forward"})
    assert r.status_code == 200, r.text
    return r.json()


def test_the_library_answers_the_same_id_for_the_same_body_and_prepares_it_once(client: Any) -> None:
    first = client.post("/elements", json=DOTS)
    assert first.status_code == 201, first.text
    again = client.post("/elements", json=DOTS)
    assert again.status_code == 200 and again.json() == first.json()
    other = client.post("/elements", json={**DOTS, "relief": "pit"})
    assert other.status_code == 201 and other.json()["id"] != first.json()["id"]
    listed = {e["id"] for e in client.get("/elements").json()}
    assert listed == {first.json()["id"], other.json()["id"]}
    detail = client.get(f"/elements/{first.json()['id']}").json()
    assert detail["body"]["layout"] == {"type": "grid", "pitch_mm": [1.0, 1.0]} and detail["features"] is None


def test_dots_on_an_edge_lit_guide_let_the_trapped_light_out_and_taking_them_off_restores_the_answer(
        client: Any) -> None:
    sid = _guide(client)
    sensor = client.post(f"/scenes/{sid}/sensors", json=ABOVE).json()["id"]
    plain = _above(client, sid, sensor)
    assert max(plain["lux"][0] + plain["lux"][1] + plain["lux"][2]) == 0.0   # total internal reflection keeps it in
    eid = client.post("/elements", json=DOTS).json()["id"]
    added = client.post(f"/scenes/{sid}/elements", json={"element": eid, "node": "backlight/guide",
                                                         "facing": [0, 0, -1]})
    assert added.status_code == 201, added.text
    assert added.json()["applied"] and added.json()["body"]["node"] == uid(1)
    dotted = _above(client, sid, sensor)
    lux, err = np.array(dotted["lux"]), np.array(dotted["stderr"])
    assert lux.sum() > 10 * np.sqrt((err ** 2).sum()) > 0
    assert client.delete(f"/scenes/{sid}/elements/{added.json()['id']}").status_code == 204
    assert client.get(f"/scenes/{sid}/elements").json() == []
    back = _above(client, sid, sensor)
    assert back["lux"] == plain["lux"] and back["stderr"] == plain["stderr"]


def test_a_pushed_mesh_feature_lights_the_guide_as_the_same_analytic_pyramid(client: Any) -> None:
    """A pyramid pushed as a mesh (its vertices and triangles in the element's body) and the analytic pyramid, each on
    a guide of its own: the same planes, so the same answer on the same seed (up to rounding of the hits)."""
    answers = []
    for feature in ({"shape": "pyramid", "base_mm": 0.6, "height_mm": 0.2}, pyramid_mesh(0.6, 0.2)):
        sid = _guide(client, name=feature["shape"])
        sensor = client.post(f"/scenes/{sid}/sensors", json=ABOVE).json()["id"]
        r = client.post("/elements", json={**DOTS, "feature": feature})
        assert r.status_code == 201, r.text
        assert client.post(f"/scenes/{sid}/elements", json={"element": r.json()["id"], "node": uid(1),
                                                            "facing": [0, 0, -1]}).status_code == 201
        answers.append(_above(client, sid, sensor))
    analytic, meshed = (np.array(a["lux"]) for a in answers)
    assert analytic.sum() > 0 and np.allclose(meshed, analytic, rtol=1e-9)
    assert client.get(f"/elements/{r.json()['id']}").json()["body"]["feature"]["triangles"] == \
        pyramid_mesh(0.6, 0.2)["triangles"]


def test_an_element_outlives_a_restart_loaded_from_the_library_not_prepared_again(
        tmp_path: Path, monkeypatch: Any) -> None:
    with make_client(tmp_path) as c:
        sid = _guide(c)
        eid = c.post("/elements", json=DOTS).json()["id"]
        aid = c.post(f"/scenes/{sid}/elements", json={"element": eid, "node": uid(1), "facing": [0, 0, -1]}
                     ).json()["id"]
        sensor = c.post(f"/scenes/{sid}/sensors", json=ABOVE).json()["id"]
        before = _above(c, sid, sensor)

    import tracer.elements

    def no_preparing(body: Any) -> Any:
        raise AssertionError("a restart prepared an element again")

    monkeypatch.setattr(tracer.elements, "prepare", no_preparing)
    with make_client(tmp_path) as c:
        listed = c.get(f"/scenes/{sid}/elements").json()
        assert [(x["id"], x["applied"]) for x in listed] == [(aid, True)]
        assert _above(c, sid, sensor)["lux"] == before["lux"]
        sid2 = _guide(c, name="second guide")   # a second scene takes the element from the library: nothing prepared
        assert c.post(f"/scenes/{sid2}/elements", json={"element": eid, "node": uid(1), "facing": [0, 0, -1]}
                      ).status_code == 201


@pytest.mark.parametrize("body, words", [
    ({**DOTS, "layout": {"type": "grid", "pitch_mm": [0.5, 1.0]}}, "smaller than the feature"),
    ({**DOTS, "layout": {"type": "density", "origin_mm": [0, 0], "size_mm": [10, 10], "fill": [[0.2, -0.1]]}},
     "outside [0, 1]"),
    ({**DOTS, "layout": {"type": "density", "origin_mm": [0, 0], "size_mm": [10, 10], "fill": [[0.2]],
                         "placement": "poisson"}}, "layout.placement must be one of ['blue_noise', 'random']"),
    ({**DOTS, "feature": {"shape": "dome", "radius_mm": 0.3}}, "missing field(s) ['height_mm']"),
    ([1, 2], "body: Input should be a valid dictionary"),
    ({**DOTS, "feature": {"shape": "corner_cube", "side_mm": -1}}, "feature.side_mm must be > 0"),
    ({**DOTS, "feature": {"shape": "corner_cube", "side_mm": 1.0, "apex_deg": 90}}, "feature: unknown field(s)"),
    ({**DOTS, "material": {"type": "lambertian", "reflectance": 1.5}}, "material.reflectance must be >= 0"),
    ({**DOTS, "material": {"type": "dielectric", "ior": 1.5}}, "material.type 'dielectric' is not a feature"),
    ({**DOTS, "material": {"type": "lambertian"}}, "material: missing field(s) ['reflectance']"),
    ({**DOTS, "feature": {**MESH, "triangles": MESH["triangles"][1:]}}, "feature.triangles: the mesh is not closed"),
    ({**DOTS, "feature": upside_down()}, "must look up, at most 89 deg from the normal"),
    ({**DOTS, "feature": {**MESH, "triangles": "0 1 2"}}, "feature.triangles must be a non-empty list"),
])
def test_a_bad_element_body_is_a_422_naming_the_field_and_the_library_is_unchanged(
        client: Any, body: Any, words: str) -> None:
    r = client.post("/elements", json=body)
    assert r.status_code == 422, r.text
    assert words in r.text
    assert client.get("/elements").json() == []


def test_an_assignment_that_cannot_go_is_a_422_and_nothing_changes(client: Any) -> None:
    sid = _guide(client, steps=True)
    eid = client.post("/elements", json=DOTS).json()["id"]
    revision = client.get(f"/scenes/{sid}").json()
    cases = [
        ({"element": "0" * 64, "node": uid(1), "facing": [0, 0, -1]}, "no element"),
        ({"element": eid, "node": uid(2), "facing": [0, 0, 1]}, "not planar"),
        ({"element": eid, "node": uid(0), "facing": [0, 0, -1]}, "no geometry of its own"),
        ({"element": eid, "node": uid(1), "facing": [0, 0, -1], "faces": [1]}, "one of the two"),
        ({"element": eid, "node": uid(1)}, "one of the two"),
        ({"element": eid, "node": uid(1), "facing": [1, 1, 1]}, "no triangle"),
        ({"element": "xyz", "node": uid(1), "facing": [0, 0, -1]}, "element"),
    ]
    for body, words in cases:
        r = client.post(f"/scenes/{sid}/elements", json=body)
        assert r.status_code == 422, (body, r.text)
        assert words in r.text, (body, r.text)
    assert client.get(f"/scenes/{sid}/elements").json() == []
    assert client.get(f"/scenes/{sid}").json() == revision


def test_a_bad_body_for_a_part_that_carries_an_element_is_its_422_not_the_409(client: Any) -> None:
    """Issue 54, item 5: the body is checked against the part's mesh before the conflict, so a bad `facing` or
    `faces` says what is wrong (it answered 409 "already carries"); a good body for the same faces still gets the
    409, naming the assignment that holds them; nothing changes."""
    sid = _guide(client)
    eid = client.post("/elements", json=DOTS).json()["id"]
    first = client.post(f"/scenes/{sid}/elements", json={"element": eid, "node": uid(1), "facing": [0, 0, -1]})
    assert first.status_code == 201, first.text
    before = (client.get(f"/scenes/{sid}").json(), client.get(f"/scenes/{sid}/elements").json())
    for body, words in (({"facing": [1, 1, 1]}, "no triangle of the part is selected"),
                        ({"faces": [0]}, "carries no B-rep face indices")):
        r = client.post(f"/scenes/{sid}/elements", json={"element": eid, "node": uid(1), **body})
        assert r.status_code == 422, (body, r.text)
        assert words in r.json()["detail"], (body, r.text)
    r = client.post(f"/scenes/{sid}/elements", json={"element": eid, "node": uid(1), "facing": [0, 0, -1]})
    assert r.status_code == 409, r.text
    assert f"already carries element assignment {first.json()['id']}" in r.json()["detail"], r.text
    assert (client.get(f"/scenes/{sid}").json(), client.get(f"/scenes/{sid}/elements").json()) == before


def test_a_guide_carries_dots_underneath_and_prisms_on_top_and_loses_one_without_the_other(client: Any) -> None:
    """Issue 53: two assignments on one node, on its bottom and its top faces, are both applied (each with its own
    support); the light above differs from that of the dots alone; deleting the prisms gives back the dots' answer
    on the same seed, bit for bit."""
    sid = _guide(client)
    sensor = client.post(f"/scenes/{sid}/sensors", json=ABOVE).json()["id"]
    dots = client.post("/elements", json=DOTS).json()["id"]
    prisms = client.post("/elements", json={"type": "microstructure", "feature": {"shape": "prism", "base_mm": 0.1,
                                                                                  "apex_deg": 100},
                                            "layout": {"type": "grid", "pitch_mm": [0.1, 0.1]}}).json()["id"]
    under = client.post(f"/scenes/{sid}/elements", json={"element": dots, "node": uid(1), "facing": [0, 0, -1]})
    assert under.status_code == 201, under.text
    alone = _above(client, sid, sensor)
    on_top = client.post(f"/scenes/{sid}/elements", json={"element": prisms, "node": uid(1), "facing": [0, 0, 1]})
    assert on_top.status_code == 201 and on_top.json()["applied"], on_top.text
    listed = {x["id"]: x for x in client.get(f"/scenes/{sid}/elements").json()}
    assert all(x["applied"] for x in listed.values()) and len(listed) == 2
    assert [listed[a.json()["id"]]["support"]["normal"] for a in (under, on_top)] == [[0, 0, -1], [0, 0, 1]]
    both = _above(client, sid, sensor)
    a, b = np.array(alone["lux"]), np.array(both["lux"])
    sigma = np.sqrt(np.array(alone["stderr"]) ** 2 + np.array(both["stderr"]) ** 2)
    assert np.abs(a - b).max() > 5 * sigma.max() > 0   # the prisms turn what the dots let out
    assert client.delete(f"/scenes/{sid}/elements/{on_top.json()['id']}").status_code == 204
    assert [x["id"] for x in client.get(f"/scenes/{sid}/elements").json()] == [under.json()["id"]]
    again = _above(client, sid, sensor)
    assert again["lux"] == alone["lux"] and again["stderr"] == alone["stderr"]


def test_the_docs_example_names_its_element_by_the_id_its_body_gets() -> None:
    from service.routes.elements import DOTS_EXAMPLE, DOTS_EXAMPLE_ID
    from tracer.elements import prepare

    assert prepare(DOTS_EXAMPLE).id == DOTS_EXAMPLE_ID


def test_the_python_client_puts_switches_lists_and_removes_an_element(client: Any) -> None:
    """Through `lumenlink.Client` (on the app's transport): taking an element off answers None once the service
    answered 204 (it raised "HTTP 204: No Content" although the removal had happened), the scene's list is empty
    again, and removing it twice is the service's 404, said as an error."""
    from lumenlink import Client
    from lumenlink.errors import LumenLinkError

    sid = _guide(client)
    lumen = Client("http://testserver", transport=client._transport)
    eid = lumen.add_element(DOTS)["id"]
    put = lumen.put_element(sid, "backlight/guide", eid, facing=[0, 0, -1])
    assert put["applied"] and [e["id"] for e in lumen.scene_elements(sid)] == [put["id"]]
    assert lumen.switch_element(sid, put["id"], eid)["id"] == put["id"]
    assert lumen.remove_element(sid, put["id"]) is None
    assert lumen.scene_elements(sid) == []
    with pytest.raises(LumenLinkError, match="404"):
        lumen.remove_element(sid, put["id"])


def test_a_density_lattice_too_costly_to_prepare_is_a_422_saying_why_before_any_work(client: Any, tmp_path: Path
                                                                                    ) -> None:
    """Issue 54, item 6: 3.9e9 sites (under the old 4e9-site cap, ~4.7 GB and about a minute to prepare before) are
    refused at once, saying what they would cost and what to change, with nothing stored; the pitch the message
    names is accepted."""
    import re
    import time

    from tracer.elements.microstructure import max_density_sites

    before = client.get("/elements").json()
    body = {"type": "microstructure", "feature": {"shape": "dome", "radius_mm": 0.0015, "height_mm": 0.001},
            "layout": {"type": "density", "origin_mm": [0, 0], "size_mm": [245.0, 183.5], "fill": [[0.5]],
                       "pitch_mm": 0.0034}}
    t0 = time.perf_counter()
    r = client.post("/elements", json=body)
    assert r.status_code == 422, r.text
    assert time.perf_counter() - t0 < 2.0           # refused before any site is drawn (that would take a minute)
    detail = r.json()["detail"]
    sites = int(re.search(r"= ([\d,]+) lattice sites", detail).group(1).replace(",", ""))
    assert 3.8e9 < sites < 4e9 and f"at most {max_density_sites():,} sites" in detail
    assert "layout.pitch_mm" in detail and "layout.size_mm" in detail and "MiB" in detail, detail
    assert client.get("/elements").json() == before
    assert not list((tmp_path / "elements").glob("*.npz")) if (tmp_path / "elements").exists() else True
    # the coarser pitch it names fits (its lattice is the largest one request prepares), checked here without
    # preparing it: a lattice at that pitch over the same face is within the bound
    pitch = float(re.search(r"pitch_mm \(at least ([\d.]+) mm", detail).group(1))
    assert int(245.0 // pitch) * int(183.5 // pitch) <= max_density_sites()


def test_a_feature_given_as_a_pushed_geometry_is_the_same_element_as_its_mesh_in_the_body(client: Any) -> None:
    """DESIGN.md's ``{"geometry": "<gid>"}``: the mesh pushed by PUT /geometries (mm; float32-exact here) is read
    into the element, so the element is the one its mesh inline gives; a geometry never pushed is a 422, and the
    library is unchanged."""
    m = pyramid_mesh(0.5, 0.25)
    gid, data = glb(np.array(m["vertices_mm"], np.float32), np.array(m["triangles"], np.uint32))
    missing = client.post("/elements", json={**DOTS, "feature": {"geometry": gid}})
    assert missing.status_code == 422 and f"feature.geometry {gid} is not pushed" in missing.text
    bad = client.post("/elements", json={**DOTS, "feature": {"geometry": "cafe"}})
    assert bad.status_code == 422 and "feature.geometry must be a geometry id" in bad.text
    mixed = client.post("/elements", json={**DOTS, "feature": {"geometry": gid, "shape": "mesh"}})
    assert mixed.status_code == 422 and "alone" in mixed.text
    assert client.get("/elements").json() == []
    assert client.put(f"/geometries/{gid}", content=data, headers={"content-type": "model/gltf-binary"}
                      ).status_code in (200, 201)
    pushed = client.post("/elements", json={**DOTS, "feature": {"geometry": gid}})
    assert pushed.status_code == 201, pushed.text
    inline = client.post("/elements", json={**DOTS, "feature": m})
    assert inline.status_code == 200 and inline.json()["id"] == pushed.json()["id"]
