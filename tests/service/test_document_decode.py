"""The push decoder's fast path accepts exactly what the schema accepts, and decodes it the same way."""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest
from pydantic import ValidationError

from service.document import decode_document
from service.schemas import DocumentPush
from service.tree import nodes_to_columns

G = "a" * 64
U = [f"00000000-0000-4000-8000-{k:012d}" for k in range(10)]
IDENT = [1.0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]


def doc() -> dict:
    return {"base_revision": 2, "length_unit": "mm",
            "source": {"name": "x.step", "tessellation": {"linear": 0.1, "relative": True}},
            "nodes": [{"uuid": U[0], "parent": None, "name": "root", "transform": IDENT, "geometry": None},
                      {"uuid": U[1], "parent": U[0], "name": "part", "transform": [float(k) for k in range(12)]
                       + [0, 0, 0, 1], "geometry": G, "color": [0.5, 1, 0]},
                      {"uuid": U[2], "parent": U[0], "transform": [1, 0, 0, 5, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]}]}


def reference(body: bytes):
    d = DocumentPush.model_validate_json(body)
    return d.model_copy(update={"nodes": []}), nodes_to_columns(d.nodes)


def same(decoded, ref) -> None:
    header, cols = ref
    assert decoded.header == header
    got = decoded.columns()
    for k in (0, 1, 2, 4, 5):
        assert got[k] == cols[k]
    np.testing.assert_array_equal(got[3], cols[3])


def test_fast_path_decodes_like_the_schema() -> None:
    body = json.dumps(doc()).encode()
    d = decode_document(body, set(), {G})
    assert d.fast
    same(d, reference(body))


def test_known_uuids_skip_nothing_but_the_format_check() -> None:
    body = json.dumps(doc()).encode()
    d = decode_document(body, set(U), {G})
    assert d.fast and d.uuids == U[:3]


MUTATIONS = {
    "uppercase uuid": lambda d: d["nodes"][1].update(uuid=U[1].upper()),
    "bool in transform": lambda d: d["nodes"][1]["transform"].__setitem__(0, True),
    "string in transform": lambda d: d["nodes"][1]["transform"].__setitem__(0, "1.0"),
    "short transform": lambda d: d["nodes"][1].update(transform=IDENT[:15]),
    "nested transform": lambda d: d["nodes"][1].update(transform=[IDENT[:4]] * 4),
    "color out of range": lambda d: d["nodes"][1].update(color=[0.5, 1.5, 0]),
    "color as string": lambda d: d["nodes"][1].update(color="red"),
    "color too short": lambda d: d["nodes"][1].update(color=[0.5, 0.5]),
    "color bool": lambda d: d["nodes"][1].update(color=[True, 0, 0]),
    "extra node key": lambda d: d["nodes"][1].update(material="steel"),
    "extra top key": lambda d: d.update(author="me"),
    "missing transform": lambda d: d["nodes"][1].pop("transform"),
    "missing uuid": lambda d: d["nodes"][1].pop("uuid"),
    "name too long": lambda d: d["nodes"][1].update(name="x" * 501),
    "name not a string": lambda d: d["nodes"][1].update(name=5),
    "unknown geometry": lambda d: d["nodes"][1].update(geometry="b" * 64),
    "bad geometry": lambda d: d["nodes"][1].update(geometry="../x"),
    "bad parent": lambda d: d["nodes"][1].update(parent="nope"),
    "node not an object": lambda d: d["nodes"].append([1, 2]),
    "nodes not a list": lambda d: d.update(nodes={"a": 1}),
    "negative base": lambda d: d.update(base_revision=-1),
    "bad unit": lambda d: d.update(length_unit="parsec"),
    "integers everywhere": lambda d: d["nodes"][0].update(transform=[1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]),
    "name containing true": lambda d: d["nodes"][0].update(name="true north"),
}


@pytest.mark.parametrize("name", sorted(MUTATIONS))
def test_fast_path_never_disagrees_with_the_schema(name: str) -> None:
    d = copy.deepcopy(doc())
    MUTATIONS[name](d)
    body = json.dumps(d).encode()
    try:
        ref = reference(body)
    except ValidationError:
        ref = None
    if ref is None:
        with pytest.raises(ValidationError):
            decode_document(body, set(), {G})
        return
    decoded = decode_document(body, set(), {G} if name != "unknown geometry" else {G, "b" * 64})
    same(decoded, ref)


@pytest.mark.parametrize("text", [b"", b"{", b"[]", b"null", b'{"nodes": [NaN]}', b'{"nodes": [], "x": Infinity}'])
def test_not_a_document(text: bytes) -> None:
    with pytest.raises(ValidationError):
        decode_document(text, set(), set())
