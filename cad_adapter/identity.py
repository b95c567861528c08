"""Node identity: a UUID per node that survives edits, re-exports, re-imports and "Save As".

The memory is the scene: :func:`identify` reconciles the document with the tree the scene holds now
(``GET /scenes/{id}/nodes``: names, product names, paths, placements, shape signatures, geometry ids), so
a file saved under a new name and pushed to the same scene keeps every UUID. Where no scene tree is
given (a first push, a document pushed to several scenes), the sidecar ``<document>.lumenlink.json``
holds the same records. :mod:`cad_adapter.matching` does the matching: a global assignment by shape
class, aligned placement and structure, never nearest-first; see its docstring for the rules.

Changes are judged with tolerances, not bit equality (:class:`Tolerance`):

* a node whose placement in its (same) parent differs from the old one by less than ``linear`` × the
  model's diagonal and ``angular`` radians keeps the old placement, bit for bit (not a move);
* a part whose B-rep is the same within ``shape_rtol`` in its own frame (volume, area, centroid, inertia
  tensor, face/edge/vertex counts) keeps the old geometry id: it is neither tessellated nor uploaded,
  and the service builds no bottom level (``Document.reuse``). Only when the scene's tessellation
  settings are the ones asked for now.

The sidecar keeps entries of nodes that have disappeared (``present: false``), so a part deleted and
restored later gets its UUID back, and with it what the simulation had assigned to it.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
import tempfile
import time
import uuid as uuidlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from OCP.Bnd import Bnd_Box
from OCP.BRepBndLib import BRepBndLib
from OCP.BRepGProp import BRepGProp
from OCP.GProp import GProp_GProps
from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_VERTEX
from OCP.TopExp import TopExp
from OCP.TopTools import TopTools_IndexedMapOfShape

from .errors import IdentityError
from .matching import RULES, reconcile
from .sides import ShapeKey, Side
from .tree import UNIT_METRES, Document

SIDECAR_FORMAT = "lumenlink-sidecar-v3"
#: v1 and v2 numbered every name shared by siblings from [0]; v3 paths follow `service.paths` (first bare, [2], …)
OLD_SIDECAR_FORMATS = ("lumenlink-sidecar-v1", "lumenlink-sidecar-v2")
SIDECAR_SUFFIX = ".lumenlink.json"
MATCH_KINDS = RULES


@dataclass(frozen=True)
class Tolerance:
    """When a difference is no change.

    Attributes
    ----------
    linear : float
        Placement tolerance, a fraction of the model's diagonal (default 1e-6).
    angular : float
        Placement tolerance in radians (default 1e-9).
    shape_rtol : float
        Same B-rep: invariants equal within this fraction of the part's size (default 1e-6).
    """

    linear: float = 1e-6
    angular: float = 1e-9
    shape_rtol: float = 1e-6

    def __post_init__(self) -> None:
        for name in ("linear", "angular", "shape_rtol"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or not 0 <= v < 1:
                raise IdentityError(f"tolerance {name} must be a number in [0, 1), got {v!r}")


def sidecar_path(document: str | Path) -> Path:
    """``<file>.lumenlink.json`` beside the document."""
    p = Path(document)
    return p.with_name(p.name + SIDECAR_SUFFIX)


def default_sidecar(document: str | Path) -> tuple[Path, str | None]:
    """Where a document's sidecar lives: beside it, or (read-only folder) in the user's cache.

    Returns
    -------
    path : pathlib.Path
    warning : str or None
        Set when the sidecar cannot sit beside the document.
    """
    beside = sidecar_path(Path(document).resolve())
    if beside.exists() or os.access(beside.parent, os.W_OK):
        return beside, None
    base = Path(os.environ.get("LUMENLINK_SIDECAR_DIR") or Path(os.environ.get("XDG_CACHE_HOME") or
                                                                 Path.home() / ".cache") / "lumenlink" / "sidecars")
    digest = hashlib.sha256(str(beside).encode()).hexdigest()[:12]
    path = base / f"{Path(document).name}-{digest}{SIDECAR_SUFFIX}"
    path.parent.mkdir(parents=True, exist_ok=True)
    return path, f"{beside.parent} is not writable: the UUID sidecar is kept in {path}"


def is_uuid(text: object) -> bool:
    if not isinstance(text, str):
        return False
    try:
        return str(uuidlib.UUID(text)) == text.lower()
    except ValueError:
        return False


# ---------------------------------------------------------------- shape signatures

def _count(shape, kind) -> int:
    m = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, kind, m)
    return int(m.Extent())


def shape_signature(shape) -> dict:
    """What identity needs of a part's B-rep (document units, the part's own frame).

    Returns
    -------
    dict
        ``volume``, ``area``; ``moments`` (3, ascending: principal moments of inertia about the centroid,
        unit density; of the surface for a shell); ``axes`` (9: the principal axes as rows); ``centroid``
        (3); ``topology`` (faces, edges, vertices); ``bbox`` (6). The first four and ``topology`` do not
        depend on the part's frame.
    """
    vprops = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape, vprops)
    sprops = GProp_GProps()
    BRepGProp.SurfaceProperties_s(shape, sprops)
    volume = abs(float(vprops.Mass()))
    props = vprops if volume > 0 else sprops
    c = props.CentreOfMass()
    m = props.MatrixOfInertia()
    inertia = np.array([[m.Value(i, j) for j in (1, 2, 3)] for i in (1, 2, 3)], dtype=np.float64)
    if float(vprops.Mass()) < 0:  # a solid with reversed orientation: OCCT gives negative mass
        inertia = -inertia
    moments, axes = np.linalg.eigh(0.5 * (inertia + inertia.T))
    box = Bnd_Box()
    BRepBndLib.AddOptimal_s(shape, box, False, False)
    bbox = [0.0] * 6 if box.IsVoid() else [float(x) for x in box.Get()]
    return {"volume": volume, "area": abs(float(sprops.Mass())),
            "moments": [float(x) for x in np.maximum(moments, 0.0)],
            "centroid": [float(c.X()), float(c.Y()), float(c.Z())],
            "axes": [float(x) for x in axes.T.ravel()],
            "topology": [_count(shape, TopAbs_FACE), _count(shape, TopAbs_EDGE), _count(shape, TopAbs_VERTEX)],
            "bbox": bbox}


def part_signature(doc: Document, key: str) -> dict:
    """The part's :func:`shape_signature`, computed once per reading."""
    part = doc.parts[key]
    if part._signature is None:
        part._signature = shape_signature(part.shape)
    return part._signature


def shape_key(sig: dict | None) -> ShapeKey | None:
    """The frame-independent part of a signature (None without one)."""
    if not sig or sig.get("moments") is None:
        return None
    topo = sig.get("topology") or (0, 0, 0)
    return ShapeKey(float(sig["volume"]), float(sig["area"]), tuple(float(x) for x in sig["moments"]),  # type: ignore[arg-type]
                    tuple(int(x) for x in topo))  # type: ignore[arg-type]


def _inertia(sig: dict) -> np.ndarray:
    axes = np.asarray(sig["axes"], dtype=np.float64).reshape(3, 3)
    return axes.T @ np.diag(sig["moments"]) @ axes


def same_brep(a: dict | None, b: dict | None, rtol: float) -> bool:
    """Whether two signatures describe the same B-rep in the same frame, within ``rtol`` of its size."""
    if not a or not b or a.get("axes") is None or b.get("axes") is None:
        return False
    ka, kb = shape_key(a), shape_key(b)
    if ka is None or kb is None or not ka.matches(kb, rtol):
        return False
    if a.get("topology") and b.get("topology") and list(a["topology"]) != list(b["topology"]):
        return False
    s = max(ka.size, kb.size)
    if np.linalg.norm(np.subtract(a["centroid"], b["centroid"])) > rtol * s:
        return False
    return bool(np.abs(_inertia(a) - _inertia(b)).max() <= rtol * (max(ka.moments[-1], kb.moments[-1]) + s ** 5))


#: invariants (volume, area, moments, centroid) this close (relative to the part's size) make a part a candidate
#: for keeping its old mesh, which then has to show the same surface within the tessellation's deflection
LOOSE_RTOL = 1e-3


def _close_brep(a: dict | None, b: dict | None) -> bool:
    """Whether two signatures are close enough (`LOOSE_RTOL`, any topology) to compare the surfaces."""
    if not a or not b or a.get("moments") is None or b.get("moments") is None or b.get("centroid") is None:
        return False
    ka, kb = shape_key({**a, "topology": None}), shape_key({**b, "topology": None})
    if ka is None or kb is None or not ka.matches(kb, LOOSE_RTOL):
        return False
    return bool(np.linalg.norm(np.subtract(a["centroid"], b["centroid"])) <= LOOSE_RTOL * max(ka.size, kb.size))


def confirm_same_surface(doc: Document, tess, fetch) -> dict[str, float]:
    """Keep the old geometry id of candidate parts (``doc.reuse_if_same_surface``) whose new mesh and old mesh show
    the same surface: symmetric Hausdorff distance at most twice the tessellation's deflection (each mesh lies
    within one deflection of its B-rep, so two of one B-rep lie within two of each other; a real change of ten
    deflections does not). A kept part moves from ``tess.meshes`` to ``doc.reuse``: not uploaded, no bottom level.

    Parameters
    ----------
    doc : Document
        After :func:`identify` (with ``reuse_geometry``).
    tess : cad_adapter.tessellate.Tessellation
        The new meshes (modified in place).
    fetch : callable(gid) -> (vertices, triangles)
        The old mesh (the service's ``GET /geometries/{gid}``).

    Returns
    -------
    dict of str to float
        Part key -> the Hausdorff distance found (document units) for every candidate compared; those within
        the bound were kept.
    """
    from .same_surface import hausdorff_within

    out: dict[str, float] = {}
    for key, gid in list(doc.reuse_if_same_surface.items()):
        mesh = tess.meshes.get(key)
        if mesh is None or mesh.geometry_id == gid:
            continue
        old_v, old_t = fetch(gid)
        bound = 2.0 * float(mesh.deflection)
        h = hausdorff_within((mesh.vertices, mesh.triangles), (old_v, old_t), bound)
        out[key] = h
        if h <= bound:
            doc.reuse[key] = gid
            del tess.meshes[key]
            tess.reused += 1
    doc.reconciliation_detail["same_surface"] = {doc.parts[k].name or k: h for k, h in out.items()}
    doc.reconciliation_detail["reused_geometries"] = len(set(doc.reuse.values()))
    return out


# ---------------------------------------------------------------- records (what the scene and the sidecar hold)

def node_records(doc: Document, geometry: dict[str, str] | None = None) -> list[dict]:
    """One record per node, in the shape ``GET /scenes/{id}/nodes`` answers (document units).

    ``geometry`` maps part keys to geometry ids (after tessellation), where known.
    """
    out = []
    for n in doc.nodes:
        if n.uuid is None:
            raise IdentityError("assign UUIDs (identify) before taking records", node=n.path)
        out.append({
            "uuid": n.uuid, "parent": doc.nodes[n.parent].uuid if n.parent is not None else None,
            "name": n.name, "product": n.product, "path": n.path,
            "transform": [float(x) for x in n.transform.ravel()],
            "world": [float(x) for x in doc.world_transform(n.index).ravel()],
            "geometry": (geometry or {}).get(n.part) if n.part else None,
            "signature": part_signature(doc, n.part) if n.part is not None else None,
            "leaf": n.part is not None,
        })
    return out


def side_from_document(doc: Document) -> Side:
    """The new side of a reconciliation (carried UUIDs as the only known ones)."""
    n = len(doc.nodes)
    world = np.stack([doc.world_transform(i) for i in range(n)]) if n else np.zeros((0, 4, 4))
    keys, centroids, axes = [], np.zeros((n, 3)), np.zeros((n, 3, 3))
    for i, node in enumerate(doc.nodes):
        sig = part_signature(doc, node.part) if node.part is not None else None
        keys.append(shape_key(sig))
        if sig:
            centroids[i] = sig["centroid"]
            axes[i] = np.reshape(sig["axes"], (3, 3))
    return Side(parent=np.array([-1 if x.parent is None else x.parent for x in doc.nodes], np.int64),
                names=[x.name for x in doc.nodes], products=[x.product for x in doc.nodes], world=world,
                local=np.stack([x.transform for x in doc.nodes]) if n else np.zeros((0, 4, 4)), keys=keys,
                centroid=centroids, leaf=np.array([x.part is not None for x in doc.nodes], bool),
                uuids=[x.carried_uuid.lower() if x.carried_uuid and is_uuid(x.carried_uuid.lower()) else None
                       for x in doc.nodes],
                paths=[x.path for x in doc.nodes], axes=axes)


def side_from_records(records: list[dict], scale: float = 1.0) -> tuple[Side, list[dict]]:
    """The old side from scene or sidecar records (and the records kept, one per uuid, in order);
    ``scale`` converts their lengths to the new unit.

    Raises
    ------
    IdentityError
        A record without a valid uuid, or a parent that is not an earlier record.
    """
    index: dict[str, int] = {}
    rows = []
    for r in records:
        if not isinstance(r, dict) or not is_uuid(r.get("uuid")):
            raise IdentityError(f"a previous node record has no valid uuid: {str(r)[:200]}")
        if r["uuid"] in index:
            continue
        index[r["uuid"]] = len(rows)
        rows.append(r)
    n = len(rows)
    parent = np.full(n, -1, np.int64)
    local, world = np.tile(np.eye(4), (n, 1, 1)), np.tile(np.eye(4), (n, 1, 1))
    keys: list[ShapeKey | None] = []
    centroids, axes = np.zeros((n, 3)), np.zeros((n, 3, 3))
    leaf = np.zeros(n, bool)
    for i, r in enumerate(rows):
        p = r.get("parent")
        if p is not None:
            parent[i] = index.get(p, -1)
        for name, arr in (("transform", local), ("world", world)):
            if r.get(name) is not None:
                arr[i] = np.asarray(r[name], dtype=np.float64).reshape(4, 4)
        sig = r.get("signature")
        keys.append(shape_key(sig))
        if sig and sig.get("centroid") is not None:
            centroids[i] = np.asarray(sig["centroid"], dtype=np.float64) * scale
        if sig and sig.get("axes") is not None:
            axes[i] = np.asarray(sig["axes"], dtype=np.float64).reshape(3, 3)
        leaf[i] = bool(r.get("leaf", r.get("geometry") is not None or sig is not None))
    if np.any(parent >= np.arange(n)):  # a parent after its child: recompute the order-dependent worlds
        raise IdentityError("previous node records must list parents before their children")
    local[:, :3, 3] *= scale
    world[:, :3, 3] *= scale
    if scale != 1.0:
        keys = [None if k is None else ShapeKey(k.volume * scale ** 3, k.area * scale ** 2,
                                                 tuple(m * scale ** 5 for m in k.moments),  # type: ignore[arg-type]
                                                 k.topology) for k in keys]
    missing_world = [i for i, r in enumerate(rows) if r.get("world") is None]
    for i in missing_world:  # sidecars of v1 and hand-made records: compose the locals
        world[i] = local[i] if parent[i] < 0 else world[parent[i]] @ local[i]
    return Side(parent, [str(r.get("name") or "") for r in rows], [str(r.get("product") or "") for r in rows],
                world, local, keys, centroids, leaf, [r["uuid"] for r in rows],
                [str(r.get("path") or "") for r in rows], axes), rows


# ---------------------------------------------------------------- sidecar

def load_sidecar(path: str | Path) -> dict:
    """The sidecar's content (``{"nodes": [records], ...}``); an empty one if there is none.

    Raises
    ------
    IdentityError
        The file exists but is not a sidecar this version understands.
    """
    p = Path(path)
    if not p.exists():
        return {"format": SIDECAR_FORMAT, "nodes": []}
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise IdentityError(f"{p}: the sidecar cannot be read ({exc}); move it away to start afresh "
                            "(every node then gets a new UUID)") from exc
    if (not isinstance(data, dict) or data.get("format") not in (SIDECAR_FORMAT, *OLD_SIDECAR_FORMATS)
            or not isinstance(data.get("nodes"), list)):
        raise IdentityError(f"{p}: not a {SIDECAR_FORMAT} sidecar file")
    for e in data["nodes"]:
        if not isinstance(e, dict) or not is_uuid(e.get("uuid")):
            raise IdentityError(f"{p}: entry {e.get('path') if isinstance(e, dict) else e!r} has an invalid uuid "
                                f"{e.get('uuid') if isinstance(e, dict) else None!r}")
        if data["format"] == "lumenlink-sidecar-v1":  # v1: paths and uuids only are trusted
            e["signature"], e["world"] = None, None
            e["leaf"] = e.get("world_centroid") is not None
        if data["format"] != SIDECAR_FORMAT and isinstance(e.get("path"), str):
            e["path"] = _renumbered(e["path"])
    return data


def _renumbered(path: str) -> str:
    """A path of a v1/v2 sidecar (shared sibling names numbered [0], [1], …) in today's rule ([0] bare, [1] → [2])."""
    def one(seg: str) -> str:
        m = re.fullmatch(r"(.*)\[(\d+)\]", seg)
        if m is None:
            return seg
        k = int(m.group(2))
        return m.group(1) if k == 0 else f"{m.group(1)}[{k + 1}]"
    return "/".join(one(s) for s in path.split("/"))


def write_sidecar(path: str | Path, doc: Document, previous: list[dict] | None = None,
                  geometry: dict[str, str] | None = None) -> Path:
    """Write the sidecar atomically (a crash never leaves half a file, which would lose every UUID)."""
    p = Path(path)
    records = node_records(doc, geometry)
    for r in records:
        r["present"] = True
    current = {r["uuid"] for r in records}
    for e in previous or []:
        if e.get("uuid") not in current:
            records.append({**e, "present": False})
    data = {"format": SIDECAR_FORMAT, "document": doc.name, "length_unit": doc.length_unit, "nodes": records}
    try:
        fd, tmp = tempfile.mkstemp(dir=p.parent, prefix=p.name + ".", suffix=".tmp")
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            json.dump(data, fh, indent=1)
        os.replace(tmp, p)
    except OSError as exc:
        raise IdentityError(f"{p}: cannot write the sidecar ({exc.strerror}); without it the UUIDs would not "
                            "survive the next import") from exc
    return p


# ---------------------------------------------------------------- identify

def _rotation_angle(a: np.ndarray, b: np.ndarray) -> float:
    """Angle (rad) of the rotation between two 3×3 frames; exact to rounding near 0 (no arccos)."""
    return float(np.linalg.norm(a - b) / math.sqrt(2.0))


def identify(doc: Document, sidecar: str | Path | None = None, write: bool = True, *,
             previous: list[dict] | None = None, previous_unit: str | None = None,
             tolerance: Tolerance | None = None, reuse_geometry: bool = False,
             removed: list[dict] | None = None) -> dict[str, int]:
    """Give every node of ``doc`` its UUID (``Node.uuid``, ``Node.match``) and fill ``doc.reconciliation``.

    Parameters
    ----------
    doc : Document
        Modified in place: UUIDs, rules, snapped placements, ``reuse`` (part key → geometry id).
    sidecar : path, optional
        Default: ``<doc.source>.lumenlink.json`` (in the user's cache when the document's folder is
        read-only); None and no source: no sidecar.
    write : bool
        Write the sidecar back.
    previous : list of dict, optional
        The scene's tree (``GET /scenes/{id}/nodes``); when it has nodes it is the memory, else the sidecar is.
    previous_unit : str, optional
        The unit of ``previous`` (the scene's); default the document's.
    tolerance : Tolerance, optional
    reuse_geometry : bool
        Keep the old geometry id of parts whose B-rep is the same within tolerance (only where the old
        meshes were made with the same tessellation settings: the caller knows).
    removed : list of dict, optional
        The scene's memory of removed nodes (``GET /scenes/{id}/removed-nodes``, same unit as ``previous``):
        a node that matches nothing present and comes back where one of them was gets its UUID (rule
        ``restored``), and with it the assignments the scene kept for it.

    Returns
    -------
    dict of str to int
        Nodes matched by each rule (:data:`MATCH_KINDS`).
    """
    t0 = time.perf_counter()
    tol = tolerance or Tolerance()
    if sidecar is None and doc.source is not None:
        sidecar, warning = default_sidecar(doc.source)
        if warning:
            doc.warnings.append(warning)
    stored = load_sidecar(sidecar) if sidecar is not None else {"nodes": []}
    from_scene = bool(previous)
    records = previous if from_scene else [e for e in stored["nodes"]]
    unit = previous_unit if from_scene else stored.get("length_unit")
    scale = UNIT_METRES[unit] / UNIT_METRES[doc.length_unit] if unit in UNIT_METRES else 1.0
    old, rows = side_from_records(records or [], scale)
    new = side_from_document(doc)
    gone, gone_rows = (side_from_records(_parents_first(removed), scale) if from_scene and removed
                       else (None, []))
    rec = reconcile(old, new, same_place_rtol=tol.linear, removed=gone)
    for i, node in enumerate(doc.nodes):
        node.uuid, node.match = rec.uuids[i], rec.rule[i]
        node.previous = rows[rec.old[i]] if rec.old[i] >= 0 else None
        if node.previous is None and len(rec.restored) and rec.restored[i] >= 0:
            node.previous = gone_rows[rec.restored[i]]
    snapped = _snap_placements(doc, rec, old, tol)
    doc.reuse = _reusable_geometry(doc, tol) if reuse_geometry and from_scene and scale == 1.0 else {}
    doc.reuse_if_same_surface = (_reusable_geometry(doc, tol, loose=True) if reuse_geometry and from_scene
                                 and scale == 1.0 else {})
    for key in doc.reuse:
        doc.reuse_if_same_surface.pop(key, None)
    counts = rec.counts()
    doc.reconciliation = {
        "matched": counts,
        "ambiguous": [{"uuid": a["uuid"], "path": a["path"], "candidates": a["candidates"], "reason": a["reason"]}
                      for a in rec.ambiguous],
        "seconds": time.perf_counter() - t0,
        "source": "scene" if from_scene else ("sidecar" if records else "none"),
    }
    doc.reconciliation_detail = {"alignment": rec.alignment.tolist(), "alignment_inliers": rec.alignment_inliers,
                                 "snapped": snapped, "reused_geometries": len(set(doc.reuse.values()))}
    if sidecar is not None and write:
        write_sidecar(sidecar, doc, stored["nodes"])
    return counts


def _parents_first(records: list[dict]) -> list[dict]:
    """Records ordered so that a parent among them comes before its children (removed at different times)."""
    by = {r.get("uuid"): r for r in records if isinstance(r, dict)}
    out: list[dict] = []
    seen: set = set()

    def visit(r: dict, depth: int = 0) -> None:
        u = r.get("uuid")
        if u in seen or depth > len(by):
            return
        p = by.get(r.get("parent"))
        if p is not None:
            visit(p, depth + 1)
        if u not in seen:
            seen.add(u)
            out.append(r)

    for r in records:
        if isinstance(r, dict):
            visit(r)
        else:
            out.append(r)  # side_from_records says what is wrong with it
    return out


def _snap_placements(doc: Document, rec, old: Side, tol: Tolerance) -> int:
    """Give the old local placement (bit for bit) to nodes that moved less than the tolerance in the same parent."""
    if len(old) == 0:
        return 0
    pts = old.world[:, :3, 3]
    diag = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))
    leaves = [n for n in doc.nodes if n.part is not None]
    if leaves:  # the model's size from its parts' boxes (node origins alone may all coincide)
        corners = []
        for n in leaves:
            b = part_signature(doc, n.part)["bbox"]
            w = doc.world_transform(n.index)
            corners.append(w[:3, :3] @ np.array(b[:3]) + w[:3, 3])
            corners.append(w[:3, :3] @ np.array(b[3:]) + w[:3, 3])
        c = np.array(corners)
        diag = max(diag, float(np.linalg.norm(c.max(axis=0) - c.min(axis=0))))
    linear = tol.linear * (diag or 1.0)
    snapped = 0
    for i, node in enumerate(doc.nodes):
        j = rec.old[i]
        if j < 0:
            continue
        parent_old = old.parent[j]
        parent_new = rec.old[node.parent] if node.parent is not None else -1
        if parent_old != parent_new:
            continue
        a, b = node.transform, old.local[j]
        if np.array_equal(a, b):
            continue
        if (np.linalg.norm(a[:3, 3] - b[:3, 3]) <= linear and _rotation_angle(a[:3, :3], b[:3, :3]) <= tol.angular
                and np.allclose(a[3], b[3])):
            node.transform = b.copy()
            snapped += 1
    return snapped


def _reusable_geometry(doc: Document, tol: Tolerance, loose: bool = False) -> dict[str, str]:
    """Parts whose every node matched an old node of one geometry id with the same B-rep in its frame.

    ``loose``: the candidates whose mesh may be kept if it shows the same surface (`confirm_same_surface`):
    invariants within `LOOSE_RTOL`, whatever the topology (a writer that split an edge)."""
    found: dict[str, str | None] = {}
    for node in doc.nodes:
        if node.part is None:
            continue
        prev = getattr(node, "previous", None)
        gid = prev.get("geometry") if prev else None
        if loose:
            ok = gid is not None and _close_brep(part_signature(doc, node.part), prev.get("signature"))
        else:
            ok = gid is not None and same_brep(part_signature(doc, node.part), prev.get("signature"),
                                               tol.shape_rtol)
        if not ok:
            found[node.part] = None
        elif node.part not in found:
            found[node.part] = gid
        elif found[node.part] != gid:
            found[node.part] = None
    return {k: v for k, v in found.items() if v is not None}

