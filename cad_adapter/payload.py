"""The pushed tree: a :class:`~cad_adapter.tree.Document` plus its tessellation as docs/DESIGN.md's JSON.

Nodes are listed parents first; ``transform`` is the node's local 4×4 flattened row-major, in the
document's ``length_unit``; ``geometry`` is the geometry id of the node's part, or null for assembly
nodes, parts without faces and parts that failed to tessellate. The service's schema forbids unknown
fields on nodes, so failures are marked in ``source.tessellation``: ``failed`` lists the affected node
UUIDs (space-separated) and ``failed_count`` counts them.
"""

from __future__ import annotations

from typing import Any

from .errors import CadAdapterError
from .tessellate import Tessellation
from .tree import Document


def _clamp01(c: tuple[float, float, float] | None) -> list[float] | None:
    if c is None:
        return None
    return [min(1.0, max(0.0, float(x))) for x in c]


#: the signature fields the service keeps (docs/DESIGN.md, identity)
WIRE_SIGNATURE = ("volume", "area", "moments", "centroid", "axes", "topology")


def build_push(doc: Document, tess: Tessellation, base_revision: int | None = None, identity: bool = True) -> dict:
    """The body of ``PUT /scenes/{id}/document`` (validates against ``service.schemas.DocumentPush``).

    Parameters
    ----------
    doc : Document
        With UUIDs assigned.
    tess : Tessellation
        Of ``doc``'s parts (its settings are recorded in ``source.tessellation``).
    base_revision : int, optional
        The scene revision this tree is based on (None: unconditional push).
    identity : bool
        Add ``identity`` (product names and shape signatures by UUID, what the next push is reconciled
        with) and ``reconciliation`` (how this push's UUIDs were found).

    Raises
    ------
    CadAdapterError
        A node without UUID (identity not assigned), or a duplicated UUID.
    """
    if base_revision is not None and (isinstance(base_revision, bool) or not isinstance(base_revision, int)
                                      or base_revision < 0):
        raise CadAdapterError(f"base_revision must be an int >= 0 or None, got {base_revision!r}")
    seen: set[str] = set()
    nodes: list[dict[str, Any]] = []
    failed: list[str] = []
    for n in doc.nodes:
        if n.uuid is None:
            raise CadAdapterError("node has no UUID: run cad_adapter.identity.identify first", node=n.path)
        if n.uuid in seen:
            raise CadAdapterError(f"UUID {n.uuid} is used by two nodes", node=n.path, uuid=n.uuid)
        seen.add(n.uuid)
        gid = None
        if n.part is not None:
            mesh = tess.meshes.get(n.part)
            if mesh is not None:
                gid = mesh.geometry_id
            elif n.part in doc.reuse:
                gid = doc.reuse[n.part]
            elif n.part in tess.failed:
                failed.append(n.uuid)
        node: dict[str, Any] = {
            "uuid": n.uuid,
            "parent": doc.nodes[n.parent].uuid if n.parent is not None else None,
            "name": n.name,
            "transform": [float(x) for x in n.transform.reshape(-1)],
            "geometry": gid,
        }
        color = _clamp01(n.color)
        if color is not None:
            node["color"] = color
        nodes.append(node)
    tess_info: dict[str, Any] = tess.settings.as_dict() if tess.settings is not None else {}
    if failed:
        tess_info["failed"] = " ".join(failed)[:100_000]   # the service bounds a source's strings
        tess_info["failed_count"] = len(failed)
    out: dict[str, Any] = {"base_revision": base_revision, "length_unit": doc.length_unit,
                           "source": {"name": doc.name, "tessellation": tess_info}}
    if identity:
        out["identity"] = identity_records(doc)
        if doc.reconciliation:
            out["reconciliation"] = doc.reconciliation
    out["nodes"] = nodes  # last: the service decodes the header apart from the node list
    return out


def identity_records(doc: Document) -> dict[str, dict]:
    """What the scene keeps per node for the next reconciliation: product name and shape signature."""
    from .identity import part_signature

    out: dict[str, dict] = {}
    for n in doc.nodes:
        sig = None
        if n.part is not None:
            s = part_signature(doc, n.part)
            sig = {k: s[k] for k in WIRE_SIGNATURE}
        out[str(n.uuid)] = {"product": n.product or None, "signature": sig}
    return out
