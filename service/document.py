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
    return Decoded(header, uuids, parents, names, t.astype(np.float64, copy=False).reshape(-1, 16), geometries,
                   colors, fast=True)
