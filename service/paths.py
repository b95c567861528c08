"""Node paths: how people name a node of a scene, and how the API turns such a name into the node's UUID.

The rule (the CAD adapter's `cad_adapter.tree.assign_paths` follows the same one):

* A node's path is the names from the root down to it, joined by ``/``. A ``/`` inside a name becomes ``∕``
  (U+2215 DIVISION SLASH) so that it cannot split the path.
* Siblings that share a name (roots count as siblings of each other) are told apart by their rank among the
  siblings of that name, in document order (the order of the pushed node list, which is the order of
  ``GET /scenes/{id}/nodes``): the first keeps the bare name, the second is ``name[2]``, the third ``name[3]``…
  So ``car/wheel``, ``car/wheel[2]``, ``car/wheel[3]``, ``car/wheel[4]``; a part that is alone among its
  siblings never carries a number, and adding a second ``wheel`` after the first does not rename the first.
* A path is stable while the document keeps its names and order; it is a name for people and scripts, not an
  identity: the API resolves a path to the node's UUID when the call is made, and what is stored (a material,
  a light ``attached_to``) hangs on the UUID, which survives renames and moves.

Wherever the API takes a node UUID (``PUT``/``DELETE /scenes/{id}/materials/{node}``, ``attached_to``, an area
light's ``node``) it also takes a path: a value that is not a UUID is a path (URL-encoded in a path parameter:
``car%2Flens``, though a plain ``car/lens`` works too). An unknown path is a 404 whose ``did_you_mean`` lists
the closest paths of the scene.
"""

from __future__ import annotations

import difflib
import fnmatch
import re
from collections.abc import Sequence
from typing import Any

from service.errors import NotFound

UUID_RE = re.compile(r"^[0-9a-fA-F]{8}-[0-9a-fA-F]{4}-[0-9a-fA-F]{4}-[0-9a-fA-F]{4}-[0-9a-fA-F]{12}$")
#: a node reference on the wire: a UUID or a path (any printable text up to 4096 characters, no control
#: characters); it is this pattern the OpenAPI document states for such parameters and fields
NODE_REF_PATTERN = r"^[^\x00-\x1f\x7f]{1,4096}$"
#: how many close paths a 404 suggests
SUGGESTIONS = 5


def is_uuid(ref: str) -> bool:
    return bool(UUID_RE.match(ref))


def segment(name: str) -> str:
    """A name as one segment of a path."""
    return name.replace("/", "\u2215")


def occurrence_paths(uuids: Sequence[str], parents: Sequence[str | None], names: Sequence[str]) -> list[str]:
    """Every node's path, from a flat node list with parent links (any order; parents need not come first).

    Ranks among same-named siblings follow the list's order. O(n).
    """
    seen: dict[tuple[str | None, str], int] = {}
    segments: list[str] = []
    for parent, name in zip(parents, names, strict=True):
        key = (parent, name)
        k = seen.get(key, 0) + 1
        seen[key] = k
        segments.append(segment(name) if k == 1 else f"{segment(name)}[{k}]")
    row = {u: i for i, u in enumerate(uuids)}
    out: list[str | None] = [None] * len(uuids)
    for start in range(len(uuids)):
        chain = []
        i: int | None = start
        while i is not None and out[i] is None:   # climb to a node whose path is known (or the root)
            chain.append(i)
            p = parents[i]
            i = row.get(p) if p is not None else None
            if len(chain) > len(uuids):
                raise ValueError("the node list has a cycle")
        prefix = out[i] if i is not None else None
        for j in reversed(chain):
            prefix = segments[j] if prefix is None else f"{prefix}/{segments[j]}"
            out[j] = prefix
    return [p or "" for p in out]


def closest(paths: Sequence[str], path: str, n: int = SUGGESTIONS) -> list[str]:
    """The paths most like `path`: first by the whole path (difflib), then any whose last segment is the
    asked one's (a node looked for in the wrong assembly), then any with the asked last segment in them."""
    out = difflib.get_close_matches(path, list(paths), n=n, cutoff=0.5)
    last = path.rsplit("/", 1)[-1].lower()
    if last:
        for p in paths:
            if len(out) >= n:
                break
            tail = p.rsplit("/", 1)[-1].lower()
            if p not in out and (tail == last or tail.split("[")[0] == last.split("[")[0]):
                out.append(p)
        tails = {p.rsplit("/", 1)[-1]: p for p in paths}
        for t in difflib.get_close_matches(path.rsplit("/", 1)[-1], list(tails), n=n, cutoff=0.6):
            if len(out) >= n:
                break
            if tails[t] not in out:
                out.append(tails[t])
    return out[:n]


def find(nodes: list[dict[str, Any]], path: str, scene_id: str) -> dict[str, Any]:
    """The node at `path` (its ``GET …/nodes`` record); 404 naming the closest paths if none is there."""
    for n in nodes:
        if n["path"] == path:
            return n
    suggestions = closest([n["path"] for n in nodes], path)
    hint = f"; did you mean {', '.join(repr(s) for s in suggestions)}?" if suggestions else \
        ("; the scene has no nodes (push a document first)" if not nodes else "")
    raise NotFound(f"no node at path {path!r} in scene {scene_id}{hint} (GET /scenes/{scene_id}/nodes lists "
                   f"every path)", path=path, did_you_mean=suggestions)


def matching(nodes: list[dict[str, Any]], pattern: str) -> list[dict[str, Any]]:
    """The nodes whose name matches the glob `pattern` (fnmatch: ``*``, ``?``, ``[abc]``; case-sensitive);
    a pattern with a ``/`` is matched against whole paths instead (``car/*/lens*``; ``*`` crosses ``/``)."""
    key = "path" if "/" in pattern else "name"
    return [n for n in nodes if fnmatch.fnmatchcase(n[key], pattern)]


def resolve(nodes: list[dict[str, Any]], ref: str, scene_id: str) -> str:
    """A node reference (a UUID, or a path) as the node's UUID (lowercase); a UUID is taken as it is (its
    existence is checked where it is used), a path must name a node of `nodes` (else 404 with suggestions)."""
    if is_uuid(ref):
        return ref.lower()
    return str(find(nodes, ref, scene_id)["uuid"])


def needs_nodes(*refs: str | None) -> bool:
    """Whether resolving these references needs the scene's node list (any of them is a path)."""
    return any(r is not None and not is_uuid(r) for r in refs)
