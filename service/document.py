"""Decoding a pushed document into tree columns: a fast path for the common case, pydantic for the rest.

A 20,000-node document is ~6 MB of JSON. Validating it into 20,000 pydantic models costs about
twice the JSON parse itself, so `decode_document` first parses with pydantic-core's JSON parser
and checks the node list column-wise (types, lengths, id formats, known ids) the way
`service.schemas.DocumentPush` would. Anything the fast path is not sure about — an unexpected
key, a non-canonical UUID, a boolean among numbers, an unknown geometry id — sends the whole
body through `DocumentPush.model_validate_json`, the single authority for what is valid and for
the wording of errors. The fast path therefore only ever accepts documents the schema accepts.
"""

from __future__ import annotations

import re
from collections.abc import Container
from dataclasses import dataclass

import numpy as np
from pydantic_core import from_json

from service.schemas import DocumentPush
from service.tree import nodes_to_columns

_UUID = re.compile(r"[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}")
_NODE_KEYS = frozenset(("uuid", "parent", "name", "transform", "geometry", "color"))
_TOP_KEYS = frozenset(("base_revision", "length_unit", "source", "nodes"))
MAX_NAME = 500  # as NodeIn.name


@dataclass
class Decoded:
    """A pushed document: its header (a `DocumentPush` with an empty node list) and its node columns."""

    header: DocumentPush
    uuids: list[str]
    parents: list[str | None]
    names: list[str]
    transforms: np.ndarray  # (n, 16) float64
    geometries: list[str | None]
    colors: list[tuple[float, float, float] | None]
    fast: bool  # True when the fast path decoded it

    def columns(self) -> tuple[list, list, list, np.ndarray, list, list]:
        return self.uuids, self.parents, self.names, self.transforms, self.geometries, self.colors


def decode_document(body: bytes, known_uuids: Container[str], known_geometries: Container[str]) -> Decoded:
    """Decode and schema-check a push body; raises pydantic's ValidationError (→ 400/422) if it is invalid.

    Parameters
    ----------
    body : the raw request body (JSON).
    known_uuids : uuids of the scene's current tree (already validated once; their format is not re-checked).
    known_geometries : geometry ids stored by the service (valid ids; others take the slow path).
    """
    fast = _fast(body, known_uuids, known_geometries)
    if fast is not None:
        return fast
    doc = DocumentPush.model_validate_json(body)
    cols = nodes_to_columns(doc.nodes)
    header = doc.model_copy(update={"nodes": []})
    return Decoded(header, *cols, fast=False)


def _fast(body: bytes, known_uuids: Container[str], known_geometries: Container[str]) -> Decoded | None:
    try:
        data = from_json(body, allow_inf_nan=False)
    except ValueError:
        return None
    if type(data) is not dict or not data.keys() <= _TOP_KEYS or type(data.get("nodes")) is not list:
        return None
    start = body.find(b'"nodes"')
    if start < 0 or b"true" in body[start:] or b"false" in body[start:]:
        return None  # a boolean among the nodes: let the schema say where
    nodes = data.pop("nodes")
    header = DocumentPush.model_validate({**data, "nodes": []})  # small; raises the schema's own errors
    cols = _columns(nodes, known_uuids, known_geometries)
    if cols is None:
        return None
    return Decoded(header, *cols, fast=True)


Columns = tuple[list, list, list, np.ndarray, list, list]


def _columns(nodes: list, known_uuids: Container[str], known_geometries: Container[str]) -> Columns | None:
    """Columns of parsed node dicts if each is certainly valid for `NodeIn` (booleans excluded beforehand)."""
    superset = _NODE_KEYS.issuperset
    if not all(type(n) is dict and superset(n) for n in nodes):
        return None
    try:
        uuids = [n["uuid"] for n in nodes]
        transforms = [n["transform"] for n in nodes]
    except KeyError:
        return None
    parents = [n.get("parent") for n in nodes]
    names = [n.get("name", "") for n in nodes]
    geometries = [n.get("geometry") for n in nodes]
    colors_in = [n.get("color") for n in nodes]
    fullmatch = _UUID.fullmatch
    for u in uuids:
        if u not in known_uuids and (type(u) is not str or fullmatch(u) is None):
            return None
    for p in parents:
        if p is not None and p not in known_uuids and (type(p) is not str or fullmatch(p) is None):
            return None
    if any(type(x) is not str for x in names) or (names and max(map(len, names)) > MAX_NAME):
        return None
    for g in geometries:
        if g is not None and g not in known_geometries:
            return None
    try:
        t = np.array(transforms)
    except (ValueError, TypeError):
        return None
    if t.dtype.kind not in "fi" or t.shape != (len(nodes), 16):
        return None
    given = [c for c in colors_in if c is not None]
    if given:  # booleans were excluded above; strings or wrong lengths show in the array's dtype and shape
        try:
            c = np.array(given)
        except (ValueError, TypeError):
            return None
        if c.dtype.kind not in "fi" or c.shape != (len(given), 3) or not ((c >= 0.0) & (c <= 1.0)).all():
            return None
    colors = [None if c is None else (float(c[0]), float(c[1]), float(c[2])) for c in colors_in]
    return uuids, parents, names, t.astype(np.float64, copy=False).reshape(-1, 16), geometries, colors


# ---------------------------------------------------------------- incremental decoding

_NODES_OPEN = re.compile(rb'"nodes"\s*:\s*\[\s*')
SEPARATORS = (b"}, {", b"},{")


@dataclass
class NodeBytes:
    """The node list of the push that made the current tree, split into one byte string per node.

    ``chunks[i]`` is the serialization of row ``i`` (without its braces). A split on ``sep`` is
    exact when no string in the list contains ``sep``: only names may hold free text, and they are
    checked. A later body split the same way can then reuse every byte-identical chunk (a complete
    node, since a piece cut inside a string has an odd number of quotes) and decode only the others.
    """

    sep: bytes
    chunks: list[bytes]
    index: dict[bytes, int]


def split_nodes(body: bytes, names: list[str] | None = None, sep: bytes | None = None
                ) -> tuple[bytes, list[bytes], bytes] | None:
    """(header bytes up to ``"nodes"``, per-node chunks, separator) of a body whose last member is the
    node list, or None when its layout is not the plain one (then nothing is reused)."""
    start = body.find(b'"nodes"')
    if start < 0:
        return None
    m_open = _NODES_OPEN.match(body, start)
    end = len(body)
    while end and body[end - 1] in b" \t\r\n":
        end -= 1
    if m_open is None or body[end - 1:end] != b"}":
        return None
    end -= 1
    while end and body[end - 1] in b" \t\r\n":
        end -= 1
    if body[end - 1:end] != b"]" or end - 1 < m_open.end():
        return None
    end -= 1
    while end > m_open.end() and body[end - 1] in b" \t\r\n":
        end -= 1
    begin = m_open.end()
    if begin == end:
        return body[:start], [], sep or SEPARATORS[0]
    if body[begin:begin + 1] != b"{" or body[end - 1:end] != b"}":
        return None
    core = body[begin + 1:end - 1]
    if sep is None:
        sep = next((s for s in SEPARATORS if s in core), SEPARATORS[0])
    if names is not None and any(sep.decode() in x for x in names):
        return None
    return body[:start], core.split(sep), sep


def remember(body: bytes, names: list[str]) -> NodeBytes | None:
    """The `NodeBytes` of an accepted body (its tree's rows in body order), or None if it cannot be split."""
    parts = split_nodes(body, names)
    if parts is None:
        return None
    _, chunks, sep = parts
    if len(chunks) != len(names):
        return None
    return NodeBytes(sep, chunks, {c: i for i, c in enumerate(chunks)})


def decode_incremental(body: bytes, previous: NodeBytes, tree, known_geometries: Container[str]
                       ) -> tuple[Decoded, NodeBytes] | None:
    """Decode a body reusing the previous push's byte-identical nodes; None if that is not possible.

    Parameters
    ----------
    previous : the `NodeBytes` of the body that produced `tree` (row i of `tree` is ``previous.chunks[i]``).
    tree : the current `service.tree.Tree`.

    Only the changed nodes are parsed (each one on its own: a piece of a wrongly split body is not
    valid JSON) and checked like the fast path does; unchanged rows are copied from `tree`.
    """
    parts = split_nodes(body, None, previous.sep)
    if parts is None:
        return None
    head, chunks, _ = parts
    try:
        header = DocumentPush.model_validate_json(head + b'"nodes": []}')
    except ValueError:
        return None
    lookup = previous.index.get
    rows = [lookup(c, -1) for c in chunks]
    fresh = [k for k, r in enumerate(rows) if r < 0]
    if len(fresh) > max(64, len(chunks) // 4):
        return None  # mostly new: a full decode is as fast
    parsed = []
    for k in fresh:
        chunk = chunks[k]
        if b"true" in chunk or b"false" in chunk:
            return None
        try:
            parsed.append(from_json(b"{" + chunk + b"}", allow_inf_nan=False))
        except ValueError:
            return None
    cols = _columns(parsed, tree.index, known_geometries)
    if cols is None:
        return None
    n = len(chunks)
    old = np.asarray(rows, dtype=np.int64)
    if not fresh and n == len(tree) and (old == np.arange(n)).all():  # nothing changed, same order
        uuids, parents, names = list(tree.uuids), list(tree.parents), list(tree.names)
        geometries, colors, transforms = list(tree.geometries), list(tree.colors), tree.local.reshape(-1, 16)
    else:
        safe = np.where(old >= 0, old, 0)  # fresh rows get a placeholder, replaced below
        take = safe.tolist()
        uuids = [tree.uuids[r] for r in take] if len(tree) else [None] * n
        parents = [tree.parents[r] for r in take] if len(tree) else [None] * n
        names = [tree.names[r] for r in take] if len(tree) else [""] * n
        geometries = [tree.geometries[r] for r in take] if len(tree) else [None] * n
        colors = [tree.colors[r] for r in take] if len(tree) else [None] * n
        transforms = tree.local.reshape(-1, 16)[safe] if len(tree) else np.empty((n, 16))
        for j, k in enumerate(fresh):
            uuids[k], parents[k], names[k], geometries[k], colors[k] = (cols[0][j], cols[1][j], cols[2][j],
                                                                        cols[4][j], cols[5][j])
            transforms[k] = cols[3][j]
    if fresh and any(previous.sep.decode() in names[k] for k in fresh):
        return None
    if n == len(previous.chunks) and len(fresh) <= 64 and (old[old >= 0] == np.flatnonzero(old >= 0)).all():
        index = dict(previous.index)  # same order: a copy (C speed) updated for the changed rows
        for k in fresh:
            index.pop(previous.chunks[k], None)
            index[chunks[k]] = k
    else:
        index = {c: i for i, c in enumerate(chunks)}
    decoded = Decoded(header, uuids, parents, names, transforms, geometries, colors, fast=True)
    return decoded, NodeBytes(previous.sep, chunks, index)
