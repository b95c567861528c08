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


# ---------------------------------------------------------------- incremental decoding

from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from service.document import decode_incremental, remember  # noqa: E402
from service.tree import Tree  # noqa: E402

NASTY_NAMES = ["door", "a}, {b", 'quote " inside', "}, {", '"}, {"uuid": "x"', "true", "back\\\\slash", "é",
               "},{", "{", "]}"]


@st.composite
def node_lists(draw) -> list[dict]:
    n = draw(st.integers(0, 8))
    nodes = []
    for k in range(n):
        node = {"uuid": U[k], "parent": U[draw(st.integers(0, k - 1))] if k and draw(st.booleans()) else None,
                "name": draw(st.sampled_from(NASTY_NAMES)),
                "transform": [1.0, 0, 0, float(draw(st.integers(-2, 2))), 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1],
                "geometry": draw(st.sampled_from([None, G]))}
        if draw(st.booleans()):
            node["color"] = [0.5, 0.25, 1.0]
        nodes.append(node)
    return nodes


def edit(draw, nodes: list[dict]) -> list[dict]:
    nodes = copy.deepcopy(nodes)
    for node in nodes:
        what = draw(st.sampled_from(["keep", "keep", "move", "rename", "drop-color", "regeometry"]))
        if what == "move":
            node["transform"][3] += 1.0
        elif what == "rename":
            node["name"] = draw(st.sampled_from(NASTY_NAMES))
        elif what == "drop-color":
            node.pop("color", None)
        elif what == "regeometry":
            node["geometry"] = None if node["geometry"] else G
    if nodes and draw(st.booleans()):  # drop a node (a leaf or not: then a parent may be missing)
        nodes.pop(draw(st.integers(0, len(nodes) - 1)))
    if draw(st.booleans()):  # insert a new one somewhere
        new = {"uuid": U[9], "parent": None, "name": draw(st.sampled_from(NASTY_NAMES)), "transform": IDENT,
               "geometry": None}
        nodes.insert(draw(st.integers(0, len(nodes))), new)
    if draw(st.integers(0, 4)) == 0:
        nodes = draw(st.permutations(nodes))
    return nodes


def body_of(nodes: list[dict], compact: bool, base: int = 1) -> bytes:
    seps = (",", ":") if compact else (", ", ": ")
    return json.dumps({"base_revision": base, "length_unit": "mm", "nodes": nodes}, separators=seps).encode()


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(node_lists(), st.data(), st.booleans())
def test_incremental_decode_equals_a_full_decode(nodes, data, compact) -> None:
    first = body_of(nodes, compact)
    d1 = decode_document(first, set(), {G})
    tree = Tree.build(*d1.columns(), "mm")
    previous = remember(first, tree.names)
    second = body_of(edit(data.draw, nodes), compact, base=2)
    full = decode_document(second, set(), {G})
    if previous is None:
        assert any(sep in x for x in tree.names for sep in ("}, {", "},{"))
        return
    inc = decode_incremental(second, previous, tree, {G})
    if inc is None:
        return  # declined: the caller decodes in full
    decoded, nb = inc
    assert decoded.header == full.header
    got, want = decoded.columns(), full.columns()
    for k in (0, 1, 2, 4, 5):
        assert got[k] == want[k]
    np.testing.assert_array_equal(got[3], want[3])
    chunks = [nb.chunk(i) for i in range(len(nb.starts))]
    assert len(chunks) == len(want[0])
    assert [json.loads(b"{" + c + b"}")["uuid"] for c in chunks] == want[0]  # chunk i is node i
    if chunks:
        assert b"{" + nb.sep.join(chunks) + b"}" in second


def test_incremental_declines_odd_layouts() -> None:
    nodes = [{"uuid": U[0], "parent": None, "name": "a", "transform": IDENT, "geometry": None},
             {"uuid": U[1], "parent": U[0], "name": "b", "transform": IDENT, "geometry": None}]
    first = body_of(nodes, False)
    tree = Tree.build(*decode_document(first, set(), set()).columns(), "mm")
    previous = remember(first, tree.names)
    assert previous is not None and len(previous.starts) == 2
    trailing = json.dumps({"nodes": nodes, "base_revision": 1}).encode()
    pretty = json.dumps({"base_revision": 1, "nodes": nodes}, indent=2).encode()
    extra = body_of(nodes, False)[:-1] + b', "x": 1}'
    for body in (trailing, pretty, extra, b"{}", b""):
        assert decode_incremental(body, previous, tree, set()) is None
    # a changed node with an unknown key is declined, so the schema reports it
    bad = copy.deepcopy(nodes)
    bad[1]["material"] = "x"
    assert decode_incremental(body_of(bad, False), previous, tree, set()) is None


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=40), st.binary(max_size=40), st.binary(max_size=40), st.integers(1, 7))
def test_common_prefix_and_suffix_across_blocks(x: bytes, y: bytes, z: bytes, block: int) -> None:
    from service.document import _common, _common_suffix

    a, b = np.frombuffer(x + y, np.uint8), np.frombuffer(x + z, np.uint8)
    p = next((i for i in range(min(len(a), len(b))) if a[i] != b[i]), min(len(a), len(b)))
    assert _common(a, b, block) == p
    c, d = np.frombuffer(y + x, np.uint8), np.frombuffer(z + x, np.uint8)
    q = next((i for i in range(min(len(c), len(d))) if c[len(c) - 1 - i] != d[len(d) - 1 - i]), min(len(c), len(d)))
    assert _common_suffix(c, d, block) == q
