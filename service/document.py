"""Decoding a pushed document into tree columns: a fast path for the common case, pydantic for the rest.

A 20,000-node document is ~6 MB of JSON. Validating it into 20,000 pydantic models costs about
twice the JSON parse itself, so `decode_document` first parses with pydantic-core's JSON parser
and checks the node list column-wise (types, lengths, id formats, known ids) the way
`service.schemas.DocumentPush` would. Anything the fast path is not sure about — an unexpected
key, a non-canonical UUID, a boolean among numbers, an unknown geometry id — sends the whole
body through `DocumentPush.model_validate_json`, the single authority for what is valid and for
the wording of errors. The fast path therefore only ever accepts documents the schema accepts.

Pushes of the same CAD document mostly repeat themselves. `remember` notes where each node
sits in an accepted body (`NodeBytes`); the next body is compared with it byte for byte
(`same_nodes`: identical node list; `decode_incremental`: the nodes before the first and after
the last differing byte are reused from the current tree, the few in between are parsed on
their own and checked like the fast path). Anything unusual declines, and the body is decoded
in full.
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
_TOP_KEYS = frozenset(("base_revision", "length_unit", "source", "identity", "reconciliation", "nodes"))
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
    start = _nodes_key(body)
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
    if not nodes:
        return [], [], [], np.zeros((0, 16)), [], []
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
        if type(u) is not str or (u not in known_uuids and fullmatch(u) is None):   # str first: a list is unhashable
            return None
    for p in parents:
        if p is not None and (type(p) is not str or (p not in known_uuids and fullmatch(p) is None)):
            return None
    if any(type(x) is not str for x in names) or (names and max(map(len, names)) > MAX_NAME):
        return None
    for g in geometries:
        if g is not None and (type(g) is not str or g not in known_geometries):
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
_NODES_KEY = re.compile(rb'"nodes"\s*:\s*\[')
SEPARATORS = (b"}, {", b"},{")
_WS = b" \t\r\n"
MAX_FRESH = 64  # at most this many changed nodes are decoded one by one; more: a full decode


_UUID_KEY = re.compile(rb'"uuid"\s*:')


def count_nodes(body: bytes) -> int:
    """How many nodes the body's node list holds, from its bytes (no decoding): the ``"uuid"`` keys after
    ``"nodes": [``. Exact for a body whose node list is its last member (as clients send it), an upper bound
    otherwise; 0 without a node list. A ``"uuid":`` inside a JSON string has its quotes escaped: it never counts."""
    at = _nodes_key(body)
    return 0 if at < 0 else len(_UUID_KEY.findall(body, at))


def _nodes_key(body: bytes) -> int:
    """Offset of the ``"nodes": [`` member, or -1.

    The header before it (``identity``, ``reconciliation``, ``source``) may hold the string
    ``"nodes"`` as a value (a product or path named so); only the first occurrence followed by
    ``: [`` is the member. Inside a JSON string that sequence cannot occur unescaped, and a
    wrong guess only truncates the header into invalid JSON, which makes the callers decline.
    """
    m = _NODES_KEY.search(body)
    return -1 if m is None else m.start()


def _core(body: bytes) -> tuple[int, int, int] | None:
    """(offset of ``"nodes"``, start, end) of the node list's inside, without its outer braces:
    ``body[start:end]`` is ``n0}<sep>{n1}…{nk`` — or None when the body's last member is not the node list."""
    at = _nodes_key(body)
    if at < 0:
        return None
    m = _NODES_OPEN.match(body, at)
    end = len(body)
    while end and body[end - 1] in _WS:
        end -= 1
    if m is None or body[end - 1:end] != b"}":
        return None
    end -= 1
    while end and body[end - 1] in _WS:
        end -= 1
    if body[end - 1:end] != b"]" or end - 1 < m.end():
        return None
    end -= 1
    while end > m.end() and body[end - 1] in _WS:
        end -= 1
    begin = m.end()
    if begin == end:
        return at, begin, begin
    if body[begin:begin + 1] != b"{" or body[end - 1:end] != b"}" or end - begin < 2:
        return None
    return at, begin + 1, end - 1


def _bytes_view(data: bytes, offset: int, count: int) -> np.ndarray:
    """A zero-copy uint8 view of ``data[offset:offset + count]``."""
    if count <= 0:
        return np.zeros(0, dtype=np.uint8)
    return np.frombuffer(data, dtype=np.uint8, count=count, offset=offset)


def _find(view: np.ndarray, sep: bytes) -> np.ndarray:
    """Start offsets of every occurrence of `sep` in the byte array `view` (vectorized)."""
    cand = np.flatnonzero(view[: len(view) - len(sep) + 1] == sep[0]) if len(view) >= len(sep) else np.zeros(0, int)
    for j in range(1, len(sep)):
        cand = cand[view[cand + j] == sep[j]]
    return cand


@dataclass
class NodeBytes:
    """Where each node of the push that made the current tree sits in its body.

    ``body[core + starts[i] : core + ends[i]]`` is row ``i``'s serialization without its braces;
    consecutive chunks are joined by ``sep``. The split is exact when no string contains ``sep``:
    only names may hold free text, and they are checked. A later body is compared with this one
    byte for byte; the nodes in the common prefix and suffix are reused, and only those in
    between are decoded (each on its own: a piece of a wrongly split body is not valid JSON,
    so a changed node cannot pass for a boundary).
    """

    sep: bytes
    body: bytes
    core: int  # offset of the first chunk in `body`
    size: int  # length of the chunk region
    starts: np.ndarray  # (n,) int64, relative to `core`
    ends: np.ndarray  # (n,) int64, relative to `core`

    def chunk(self, k: int) -> bytes:
        return self.body[self.core + int(self.starts[k]):self.core + int(self.ends[k])]


def remember(body: bytes, names: list[str]) -> NodeBytes | None:
    """The `NodeBytes` of an accepted body (its tree's rows in body order), or None if it cannot be split."""
    where = _core(body)
    if where is None:
        return None
    _, begin, end = where
    view = _bytes_view(body, begin, end - begin)
    if len(names) == 0:
        return NodeBytes(SEPARATORS[0], body, begin, end - begin, np.zeros(0, np.int64), np.zeros(0, np.int64))
    for sep in SEPARATORS:
        hits = _find(view, sep)
        if len(hits) == len(names) - 1:
            break
    else:
        return None
    if any(sep.decode() in x for x in names):
        return None
    starts = np.concatenate([[0], hits + len(sep)]).astype(np.int64)
    ends = np.concatenate([hits, [end - begin]]).astype(np.int64)
    return NodeBytes(sep, body, begin, end - begin, starts, ends)


def _common(a: np.ndarray, b: np.ndarray, block: int = 1 << 18) -> int:
    """Length of the common prefix of two byte arrays (compared block by block: stops at the first change)."""
    m = min(len(a), len(b))
    for s in range(0, m, block):
        e = min(m, s + block)
        neq = a[s:e] != b[s:e]
        k = int(np.argmax(neq))
        if neq[k]:
            return s + k
    return m


def _common_suffix(a: np.ndarray, b: np.ndarray, block: int = 1 << 18) -> int:
    """Length of the common suffix of two byte arrays (forward-strided blocks from the end)."""
    m = min(len(a), len(b))
    la, lb = len(a), len(b)
    for s in range(0, m, block):
        e = min(m, s + block)
        neq = a[la - e:la - s] != b[lb - e:lb - s]
        if neq.any():
            return s + (e - s) - 1 - int(np.flatnonzero(neq)[-1])
    return m


def decode_incremental(body: bytes, previous: NodeBytes, tree, known_geometries: Container[str]
                       ) -> tuple[Decoded, NodeBytes] | None:
    """Decode a body reusing the previous push's unchanged nodes; None if that is not possible.

    Parameters
    ----------
    previous : the `NodeBytes` of the body that produced `tree` (row i of `tree` is chunk i).
    tree : the current `service.tree.Tree`.

    The node region is compared with the previous one: nodes inside the common prefix and the
    common suffix are copied from `tree`; the few in between are parsed one by one and checked
    like the fast path does. Costs one vectorized byte comparison plus the changed nodes.
    """
    where = _core(body)
    if where is None:
        return None
    at, begin, end = where
    try:
        header = DocumentPush.model_validate_json(body[:at] + b'"nodes": []}')
    except ValueError:
        return None
    sep = previous.sep
    n1, len1, len2 = len(previous.starts), previous.size, end - begin
    k0, k1 = _unchanged_chunks(previous, _bytes_view(body, begin, len2))
    starts1, ends1 = previous.starts, previous.ends
    delta = len2 - len1
    g0 = int(ends1[k0 - 1]) if k0 > 0 else 0  # the new body's prefix part ends here …
    g1 = int(starts1[k1]) + delta if k1 < n1 else len2  # … and its suffix part starts here
    if g1 < g0:
        return None
    fresh = _fresh_bytes(body[begin + g0:begin + g1], sep, g0, has_prefix=k0 > 0, has_suffix=k1 < n1)
    if fresh is None:
        return None
    inner, lo = fresh
    middle: list[bytes] = inner.split(sep) if inner else []
    if len(middle) > MAX_FRESH:
        return None
    cols = _fresh_columns(middle, sep, tree.index, known_geometries)
    if cols is None:
        return None
    uuids, parents, names, transforms, geometries, colors = _merged_columns(tree, cols, k0, k1, n1)
    starts, ends = _merged_offsets(previous, middle, k0, k1, lo, delta)
    decoded = Decoded(header, uuids, parents, names, np.ascontiguousarray(transforms, dtype=np.float64), geometries,
                      colors, fast=True)
    return decoded, NodeBytes(sep, body, begin, len2, starts, ends)


def _unchanged_chunks(previous: NodeBytes, b: np.ndarray) -> tuple[int, int]:
    """(k0, k1): the previous chunks 0..k0-1 lie in the common byte prefix of the node regions, and the chunks
    k1.. in their common suffix (k0 <= k1); only the chunks in between can have changed."""
    n1, len1, len2 = len(previous.starts), previous.size, len(b)
    a = _bytes_view(previous.body, previous.core, len1)
    p = _common(a, b)
    q = _common_suffix(a[min(p, len1):], b[min(p, len2):])
    k0 = int(np.searchsorted(previous.ends, p, side="right")) if n1 else 0  # chunks 0..k0-1 lie in the prefix
    k1 = int(np.searchsorted(previous.starts, len1 - q, side="left")) if n1 else 0  # chunks k1.. lie in the suffix
    return k0, max(k1, k0)


def _fresh_bytes(gap: bytes, sep: bytes, g0: int, has_prefix: bool, has_suffix: bool) -> tuple[bytes, int] | None:
    """(the changed chunks joined by `sep`, their offset in the node region) from the bytes `gap` between the
    reused prefix (ending at `g0`) and suffix; None when the separators around them are not where they must be."""
    L = len(sep)
    lo = g0
    if not gap:
        if has_prefix and has_suffix:
            return None  # two chunks with no separator between them
        inner = b""
    elif has_prefix and has_suffix:
        if gap == sep:
            inner = b""
        elif len(gap) > 2 * L and gap[:L] == sep and gap[-L:] == sep:
            inner, lo = gap[L:-L], g0 + L
        else:
            return None
    elif has_prefix:
        if gap[:L] != sep or len(gap) == L:
            return None
        inner, lo = gap[L:], g0 + L
    elif has_suffix:
        if gap[-L:] != sep or len(gap) == L:
            return None
        inner = gap[:-L]
    else:
        inner = gap
    return inner, lo


def _fresh_columns(middle: list[bytes], sep: bytes, known_uuids: Container[str],
                   known_geometries: Container[str]) -> Columns | None:
    """Columns of the changed chunks, each parsed on its own and checked like the fast path; None if any is
    doubtful, or if a name holds `sep` (the next push's split would be wrong)."""
    parsed = []
    for chunk in middle:
        if b"true" in chunk or b"false" in chunk:
            return None
        try:
            parsed.append(from_json(b"{" + chunk + b"}", allow_inf_nan=False))
        except ValueError:
            return None
    cols = _columns(parsed, known_uuids, known_geometries)
    if cols is None or any(sep.decode() in x for x in cols[2]):
        return None
    return cols


def _merged_columns(tree, cols: Columns, k0: int, k1: int, n1: int) -> Columns:
    """The new tree's columns: rows 0..k0-1 and k1..n1-1 of `tree`, with the changed rows `cols` in between."""
    fresh = len(cols[0])
    rows = np.concatenate([np.arange(k0), np.full(fresh, -1), np.arange(k1, n1)]).astype(np.int64)
    n = len(rows)
    if n == n1 == len(tree) and fresh == k1 - k0:  # nodes edited in place: copy the columns, patch
        uuids, parents, names = list(tree.uuids), list(tree.parents), list(tree.names)
        geometries, colors = list(tree.geometries), list(tree.colors)
        transforms = tree.local.reshape(-1, 16).copy() if fresh else tree.local.reshape(-1, 16)
    else:
        safe = np.where(rows >= 0, rows, 0).tolist() if len(tree) else [0] * n
        pick = (lambda col: [col[r] for r in safe]) if len(tree) else (lambda col: [None] * n)
        uuids, parents, names = pick(tree.uuids), pick(tree.parents), pick(tree.names)
        geometries, colors = pick(tree.geometries), pick(tree.colors)
        transforms = tree.local.reshape(-1, 16)[safe] if len(tree) else np.empty((n, 16))
    for j in range(fresh):
        k = k0 + j
        uuids[k], parents[k], names[k], geometries[k], colors[k] = (cols[0][j], cols[1][j], cols[2][j],
                                                                    cols[4][j], cols[5][j])
        transforms[k] = cols[3][j]
    return uuids, parents, names, transforms, geometries, colors


def _merged_offsets(previous: NodeBytes, middle: list[bytes], k0: int, k1: int, lo: int,
                    delta: int) -> tuple[np.ndarray, np.ndarray]:
    """(starts, ends) of each chunk of the new body, relative to its node region: the reused chunks where they
    were (those after the change shifted by `delta`), the changed ones laid out from `lo`."""
    mid_starts, mid_ends, pos = [], [], lo
    for chunk in middle:
        mid_starts.append(pos)
        mid_ends.append(pos + len(chunk))
        pos += len(chunk) + len(previous.sep)
    starts1, ends1 = previous.starts, previous.ends
    starts = np.concatenate([starts1[:k0], np.asarray(mid_starts, np.int64), starts1[k1:] + delta]).astype(np.int64)
    ends = np.concatenate([ends1[:k0], np.asarray(mid_ends, np.int64), ends1[k1:] + delta]).astype(np.int64)
    return starts, ends


def same_nodes(body: bytes, previous: NodeBytes) -> DocumentPush | None:
    """The header of `body` if its node list is byte for byte the previous push's (the tree is then the
    current one: an identical re-push), else None. One vectorized comparison, no copy."""
    where = _core(body)
    if where is None:
        return None
    at, begin, end = where
    if end - begin != previous.size:
        return None
    if not np.array_equal(_bytes_view(body, begin, end - begin), _bytes_view(previous.body, previous.core,
                                                                              previous.size)):
        return None
    try:
        return DocumentPush.model_validate_json(body[:at] + b'"nodes": []}')
    except ValueError:
        return None
