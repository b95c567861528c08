"""An element assigned to a part's B-rep faces (issue 36): the adapter pushes each triangle's B-rep face index, the
service keeps it with the mesh, and ``"faces": [k]`` selects that face's triangles, whatever tolerance the part was
tessellated with; a mesh pushed without face indices is valid as before, and a bad ``faces`` is a 422 that changes
nothing."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from service_helpers import glb, make_client, node, uid

from tests.tracer.transport_scenes import box

cq = pytest.importorskip("cadquery")

from cad_adapter.glb import decode_glb_faces, encode_glb  # noqa: E402
from cad_adapter.tessellate import face_table, mesh_shape  # noqa: E402
from tracer.geometry_id import geometry_id  # noqa: E402

DOTS = {"type": "microstructure", "feature": {"shape": "dome", "radius_mm": 0.3, "height_mm": 0.15},
        "layout": {"type": "grid", "pitch_mm": [1.0, 1.0]}}
COARSE, FINE = (0.5, 0.8), (0.01, 0.05)   # (linear mm, angular rad)


@pytest.fixture(scope="module")
def plate() -> Any:
    """A 60 x 40 x 3 mm light guide whose top edges are rounded (r = 1 mm): its curved faces mesh differently at
    each tolerance, its bottom stays one planar rectangle."""
    return cq.Workplane("XY").box(60, 40, 3, centered=(False, False, False)).edges(">Z").fillet(1.0).val().wrapped


@pytest.fixture
def client(tmp_path: Path) -> Any:
    with make_client(tmp_path) as c:
        yield c


def _bottom(plate: Any) -> int:
    """The bottom face's B-rep index, as the adapter names it (`face_table`)."""
    faces = [f for f in face_table(plate) if f["normal"] is not None and f["normal"][2] < -0.999]
    assert len(faces) == 1 and faces[0]["area"] == pytest.approx(2400.0)
    return int(faces[0]["face"])


def _upload(client: Any, plate: Any, linear: float, angular: float) -> tuple[str, Any]:
    mesh, _ = mesh_shape(plate, linear, angular)
    data = encode_glb(mesh.vertices, mesh.triangles, mesh.normals, mesh.face_ids)
    r = client.put(f"/geometries/{mesh.geometry_id}", content=data, headers={"content-type": "model/gltf-binary"})
    assert r.status_code in (200, 201), r.text
    assert r.json()["faces"] is True
    return mesh.geometry_id, mesh


def _push(client: Any, sid: str, gid: str, base: int) -> dict:
    nodes = [node(uid(0), None, "backlight"), node(uid(1), uid(0), "guide", geometry=gid)]
    r = client.put(f"/scenes/{sid}/document", json={"base_revision": base, "length_unit": "mm", "nodes": nodes})
    assert r.status_code == 200, r.text
    return r.json()


def test_the_adapter_names_each_triangle_s_b_rep_face_and_the_glb_carries_it(plate: Any) -> None:
    bottom = _bottom(plate)
    for linear, angular in (COARSE, FINE):
        mesh, _ = mesh_shape(plate, linear, angular)
        on = mesh.face_ids == bottom
        corners = mesh.vertices[mesh.triangles[on]].astype(np.float64)
        assert (corners[..., 2] == 0.0).all()   # the bottom face's triangles, and all of them
        area = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
        assert area.sum() == pytest.approx(2400.0, rel=1e-6)
        low = mesh.vertices[mesh.triangles].astype(np.float64)[..., 2].max(axis=1) == 0.0
        assert (low == on).all()
        v, f, n, faces = decode_glb_faces(encode_glb(mesh.vertices, mesh.triangles, mesh.normals, mesh.face_ids))
        assert faces is not None and faces.tobytes() == mesh.face_ids.tobytes()
        assert geometry_id(v, f, n, faces) == mesh.geometry_id != geometry_id(v, f, n)
    coarse, fine = mesh_shape(plate, *COARSE)[0], mesh_shape(plate, *FINE)[0]
    assert len(fine.triangles) > 2 * len(coarse.triangles)   # another tessellation, the bottom's triangles moved
    assert np.flatnonzero(fine.face_ids == bottom)[0] != np.flatnonzero(coarse.face_ids == bottom)[0]


def test_an_element_on_b_rep_faces_stays_on_the_same_face_when_the_part_is_tessellated_again(
        client: Any, plate: Any) -> None:
    bottom = _bottom(plate)
    sid = client.post("/scenes", json={"name": "faces"}).json()["id"]
    coarse, _ = _upload(client, plate, *COARSE)
    _push(client, sid, coarse, 0)
    eid = client.post("/elements", json=DOTS).json()["id"]
    r = client.post(f"/scenes/{sid}/elements", json={"element": eid, "node": uid(1), "faces": [bottom]})
    assert r.status_code == 201, r.text
    first = r.json()
    assert first["applied"] and first["support"]["normal"] == pytest.approx([0.0, 0.0, -1.0])
    assert first["support"]["size_mm"] == pytest.approx([60.0, 40.0])
    fine, mesh = _upload(client, plate, *FINE)
    answer = _push(client, sid, fine, 1)
    assert answer["geometry_changed"] == [uid(1)]
    after = client.get(f"/scenes/{sid}/elements/{first['id']}").json()
    assert after["applied"] and after["problem"] is None
    assert after["support"]["normal"] == pytest.approx([0.0, 0.0, -1.0])
    assert after["support"]["size_mm"] == pytest.approx([60.0, 40.0])
    assert after["support"]["triangles"] == int((mesh.face_ids == bottom).sum())


def test_a_bad_faces_is_a_422_naming_it_and_a_mesh_without_face_indices_is_valid_as_before(
        client: Any, plate: Any) -> None:
    sid = client.post("/scenes", json={"name": "bad faces"}).json()["id"]
    coarse, _ = _upload(client, plate, *COARSE)
    v, t = box([0, 0, 0], [10, 10, 1])
    plain, data = glb(v.astype(np.float32), t)   # an old payload: no _FEATURE_ID_0
    r = client.put(f"/geometries/{plain}", content=data, headers={"content-type": "model/gltf-binary"})
    assert r.status_code in (200, 201) and r.json()["faces"] is False
    nodes = [node(uid(0), None, "root"), node(uid(1), uid(0), "guide", geometry=coarse),
             node(uid(2), uid(0), "plain", geometry=plain)]
    assert client.put(f"/scenes/{sid}/document", json={"base_revision": 0, "length_unit": "mm", "nodes": nodes}
                      ).status_code == 200
    eid = client.post("/elements", json=DOTS).json()["id"]
    before = client.get(f"/scenes/{sid}").json()
    for body, field in (({"node": uid(1), "faces": [99]}, "faces[0]"),
                        ({"node": uid(2), "faces": [0]}, "faces"),
                        ({"node": uid(1), "faces": [0], "facing": [0, 0, -1]}, "facing"),
                        ({"node": uid(1), "faces": []}, "faces")):
        r = client.post(f"/scenes/{sid}/elements", json={"element": eid, **body})
        assert r.status_code == 422 and field in r.text, (body, r.text)
    assert client.get(f"/scenes/{sid}/elements").json() == []
    assert client.get(f"/scenes/{sid}").json() == before
    ok = client.post(f"/scenes/{sid}/elements", json={"element": eid, "node": uid(2), "facing": [0, 0, 1]})
    assert ok.status_code == 201 and ok.json()["support"]["size_mm"] == pytest.approx([10.0, 10.0])


def test_an_area_light_on_b_rep_faces_emits_from_that_face_and_a_bad_faces_is_a_422(client: Any, plate: Any) -> None:
    """An LED's chosen face by B-rep index (issue 53): the light on the guide's bottom face carries Φ = M × its
    2400 mm², whatever the rounded edges' tessellation; a face the part lacks, `faces` beside `facing`, or `faces` on
    a part pushed without face indices is a 422 naming what is wrong, nothing stored."""
    from tracer.optics.lights import pack_lights

    bottom = _bottom(plate)
    sid = client.post("/scenes", json={"name": "led face"}).json()["id"]
    coarse, _ = _upload(client, plate, *COARSE)
    v, t = box([0, 0, 0], [10, 10, 1])
    plain, data = glb(v.astype(np.float32), t)
    assert client.put(f"/geometries/{plain}", content=data,
                      headers={"content-type": "model/gltf-binary"}).status_code in (200, 201)
    nodes = [node(uid(0), None, "root"), node(uid(1), uid(0), "guide", geometry=coarse),
             node(uid(2), uid(0), "plain", geometry=plain)]
    assert client.put(f"/scenes/{sid}/document", json={"base_revision": 0, "length_unit": "mm", "nodes": nodes}
                      ).status_code == 200
    before = client.get(f"/scenes/{sid}").json()
    for body, words in (({"node": uid(1), "faces": [99]}, "no triangle of the emitting parts lies on B-rep face 99"),
                        ({"node": uid(2), "faces": [0]}, "carries no B-rep face indices"),
                        ({"node": uid(1), "faces": [bottom], "facing": [0, 0, -1]}, "not both"),
                        ({"node": uid(1), "faces": []}, "faces"),
                        ({"node": uid(1), "faces": [-3]}, "faces")):
        r = client.post(f"/scenes/{sid}/lights", json={"type": "area", "exitance_lm_m2": 1000.0, **body})
        assert r.status_code == 422 and words in r.text, (body, r.text)
    assert client.get(f"/scenes/{sid}/lights").json() == []
    assert client.get(f"/scenes/{sid}").json() == before
    r = client.post(f"/scenes/{sid}/lights", json={"type": "area", "node": uid(1), "exitance_lm_m2": 1000.0,
                                                   "faces": [bottom]})
    assert r.status_code == 201, r.text
    live = client.app.state.live.get(sid)
    L = pack_lights(live.lights, live.tracer)
    assert L.flux_total[0] == pytest.approx(1000.0 * 60e-3 * 40e-3, rel=1e-6)   # the bottom face alone, m²
