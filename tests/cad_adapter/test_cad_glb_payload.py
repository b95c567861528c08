"""GLB round trip (ours and the service's decoder) and the pushed JSON against the service schema."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest
from cad_helpers import AS1, COARSE, S1C5, STAMP, car, needs_fixtures

import cad_adapter
from cad_adapter.errors import CadAdapterError
from cad_adapter.glb import decode_glb, decode_glb_faces, encode_glb
from tracer.geometry_id import geometry_id

HAVE_SCHEMA = importlib.util.find_spec("service.schemas") is not None
needs_schema = pytest.mark.skipif(not HAVE_SCHEMA, reason="service/schemas.py does not exist yet (issue 5)")


def service_decode(data: bytes):
    from service.meshes import decode_glb as svc

    m = svc(data)
    return m.vertices, m.triangles, m.normals, m.face_ids


@needs_fixtures
@pytest.mark.parametrize("path", [AS1, STAMP], ids=["as1", "stamp"])
def test_glb_round_trip_keeps_the_geometry_id(path) -> None:
    doc = cad_adapter.read_document(path, write_sidecar=False)
    t = cad_adapter.tessellate(doc, linear=0.5, angular=0.8)
    decoders = [decode_glb_faces]
    try:  # the service's own decoder, when the service (and the tracer it imports) is importable
        import service.meshes  # noqa: F401

        decoders.append(service_decode)
    except ImportError:
        pass
    for mesh in t.meshes.values():
        data = encode_glb(mesh.vertices, mesh.triangles, mesh.normals, mesh.face_ids)
        for decode in decoders:
            v, f, n, faces = decode(data)
            assert v.tobytes() == mesh.vertices.tobytes() and f.tobytes() == mesh.triangles.tobytes()
            assert n is not None and n.tobytes() == mesh.normals.tobytes()
            assert faces is not None and faces.tobytes() == mesh.face_ids.tobytes()
            assert geometry_id(v, f, n, faces) == mesh.geometry_id


def test_glb_without_normals(rng) -> None:
    v = rng.normal(size=(10, 3))
    f = rng.integers(0, 10, size=(6, 3))
    data = encode_glb(v, f)
    v2, f2, n2 = decode_glb(data)
    assert n2 is None
    assert geometry_id(v2, f2) == geometry_id(v, f)


@pytest.mark.parametrize("v, f, match", [
    (np.zeros((3, 2)), np.zeros((1, 3), int), "shape"),
    (np.array([[0, 0, 0], [1, 0, 0], [np.nan, 0, 0]]), np.array([[0, 1, 2]]), "not finite"),
    (np.eye(3), np.array([[0, 1, 3]]), "indices"),
    (np.eye(3), np.zeros((0, 3), int), "empty"),
])
def test_glb_bad_input(v, f, match) -> None:
    with pytest.raises(CadAdapterError, match=match):
        encode_glb(v, f)


def test_glb_decode_garbage() -> None:
    with pytest.raises(CadAdapterError, match="GLB"):
        decode_glb(b"not a glb at all")


@pytest.mark.parametrize("data", [b"not a glb at all", b"glTF" + bytes([1, 0, 0, 0]) + b"\0" * 24,
                                  b"glTF" + bytes([2, 0, 0, 0, 99, 0, 0, 0]) + b"\0" * 12])
def test_one_decoder_on_both_sides(data) -> None:
    """The adapter and the service decode with the one decoder (lumenlink.glb): the same bytes are refused
    for the same reason on both sides (the service's 422 detail is the adapter's message)."""
    from service.errors import Invalid

    with pytest.raises(CadAdapterError) as ours:
        decode_glb(data)
    with pytest.raises(Invalid) as theirs:
        service_decode(data)
    assert str(ours.value) == f"not a readable GLB: {theirs.value}"


def check_schema(body: dict) -> None:
    from service.schemas import DocumentPush

    parsed = DocumentPush.model_validate(body)
    assert len(parsed.nodes) == len(body["nodes"])


@needs_schema
def test_car_push_validates_against_the_service_schema() -> None:
    doc = cad_adapter.read_document(car())
    t = cad_adapter.tessellate(doc, **COARSE)
    body = cad_adapter.build_push(doc, t, base_revision=3)
    check_schema(body)
    assert body["length_unit"] == "mm" and body["base_revision"] == 3
    assert body["source"]["tessellation"] == {"linear": 1.0, "angular": 0.8, "relative": False}
    by_name = {n["name"]: n for n in body["nodes"]}
    assert by_name["car"]["parent"] is None and by_name["car"]["geometry"] is None
    assert by_name["lens"]["parent"] == by_name["headlamp"]["uuid"]
    assert len({by_name[f"wheel_{w}"]["geometry"] for w in ("fl", "fr", "rl", "rr")}) == 1
    # transforms are row-major: the translation sits in elements 3, 7, 11
    t_fl = by_name["wheel_fl"]["transform"]
    assert t_fl[12:] == [0.0, 0.0, 0.0, 1.0] and t_fl[3] > 0 and t_fl[7] > 0


@needs_schema
@needs_fixtures
@pytest.mark.parametrize("path", [AS1, STAMP, S1C5], ids=["as1", "stamp", "s1c5"])
def test_fixture_push_validates_against_the_service_schema(path) -> None:
    doc = cad_adapter.read_document(path, write_sidecar=False)
    body = cad_adapter.build_push(doc, cad_adapter.tessellate(doc, linear=0.5, angular=0.8))
    check_schema(body)
    assert body["length_unit"] == doc.length_unit
    if path == STAMP:  # faceless leaves: nodes without geometry, not failures
        assert sum(n["geometry"] is None for n in body["nodes"]) >= 4
        assert "failed" not in body["source"]["tessellation"]


def test_build_push_bad_input() -> None:
    doc = cad_adapter.read_document(car())
    t = cad_adapter.tessellate(doc, **COARSE)
    with pytest.raises(CadAdapterError, match="base_revision"):
        cad_adapter.build_push(doc, t, base_revision=-1)
    doc.nodes[2].uuid = doc.nodes[1].uuid
    with pytest.raises(CadAdapterError, match="used by two nodes"):
        cad_adapter.build_push(doc, t)
    doc.nodes[2].uuid = None
    with pytest.raises(CadAdapterError, match="no UUID"):
        cad_adapter.build_push(doc, t)
