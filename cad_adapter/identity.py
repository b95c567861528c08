"""Node identity: a UUID per node that survives edits, re-exports and re-imports.

Sources, in order (the first that answers wins; ``Node.match`` records which):

1. ``carried``   a UUID the document itself carries (cadquery node metadata ``uuid``, a STEP attribute).
2. ``path``      the sidecar entry with the same occurrence path (a moved or edited part keeps its UUID).
3. ``signature`` the sidecar entry whose part has the same geometric signature (volume, area, centroid
                 and bounding box in the part's frame, within a relative tolerance); among several (a
                 part used many times) the one whose recorded world position is nearest. A renamed part
                 keeps its UUID this way, and so does a node whose parent was renamed.
4. ``children``  an assembly node not found so far takes the UUID its matched children's former parent
                 had (a renamed sub-assembly).
5. ``new``       a fresh ``uuid4``.

The sidecar ``<document>.lumenlink.json`` records, per node, the UUID, the occurrence path, the parent's
UUID and the signature. Entries of nodes that have disappeared are kept (``present: false``) so that a
part deleted and restored later gets its UUID back, and with it what the simulation had assigned to it.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import tempfile
import uuid as uuidlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from OCP.Bnd import Bnd_Box
from OCP.BRepBndLib import BRepBndLib
from OCP.BRepGProp import BRepGProp
from OCP.GProp import GProp_GProps

from .errors import IdentityError
from .tree import Document

SIDECAR_FORMAT = "lumenlink-sidecar-v1"
SIDECAR_SUFFIX = ".lumenlink.json"
#: relative tolerance of the signature comparison (volumes, areas and lengths scaled by the part size)
SIGNATURE_RTOL = 1e-5
MATCH_KINDS = ("carried", "path", "signature", "children", "new")


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


@dataclass(frozen=True)
class Signature:
    """Geometric signature of a part in its own frame (document units).

    Attributes
    ----------
    volume, area : float
    centroid : tuple of 3 float
        Centre of volume (centre of area for a shell).
    bbox : tuple of 6 float
        xmin, ymin, zmin, xmax, ymax, zmax.
    """

    volume: float
    area: float
    centroid: tuple[float, float, float]
    bbox: tuple[float, float, float, float, float, float]

    @property
    def size(self) -> float:
        b = self.bbox
        return math.sqrt((b[3] - b[0]) ** 2 + (b[4] - b[1]) ** 2 + (b[5] - b[2]) ** 2)

    def matches(self, other: Signature, rtol: float = SIGNATURE_RTOL) -> bool:
        """Equal within ``rtol`` of the part's size (size³ for volumes, size² for areas)."""
        s = max(self.size, other.size)
        if s == 0:
            return self == other
        tol = rtol * s
        return (abs(self.volume - other.volume) <= tol * s * s
                and abs(self.area - other.area) <= tol * s
                and all(abs(a - b) <= tol for a, b in zip(self.centroid, other.centroid, strict=True))
                and all(abs(a - b) <= tol for a, b in zip(self.bbox, other.bbox, strict=True)))

    def as_dict(self) -> dict:
        return {"volume": self.volume, "area": self.area, "centroid": list(self.centroid), "bbox": list(self.bbox)}

    @classmethod
    def from_dict(cls, d: dict) -> Signature:
        return cls(float(d["volume"]), float(d["area"]), tuple(float(x) for x in d["centroid"]),
                   tuple(float(x) for x in d["bbox"]))


def shape_signature(shape) -> Signature:
    """Volume, area, centroid and tight bounding box of a shape (document units)."""
    vprops = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape, vprops)
    sprops = GProp_GProps()
    BRepGProp.SurfaceProperties_s(shape, sprops)
    volume = float(vprops.Mass())
    props = vprops if abs(volume) > 0 else sprops
    c = props.CentreOfMass()
    box = Bnd_Box()
    BRepBndLib.AddOptimal_s(shape, box, False, False)
    bbox = (0.0,) * 6 if box.IsVoid() else tuple(float(x) for x in box.Get())
    return Signature(abs(volume), float(sprops.Mass()), (float(c.X()), float(c.Y()), float(c.Z())), bbox)


def part_signature(doc: Document, key: str) -> Signature:
    part = doc.parts[key]
    if part._signature is None:
        part._signature = shape_signature(part.shape)
    return part._signature


@dataclass
class _Entry:
    uuid: str
    path: str
    name: str
    parent: str | None
    signature: Signature | None
    world_centroid: tuple[float, float, float] | None
    present: bool = True


def load_sidecar(path: str | Path) -> list[_Entry]:
    """Entries of a sidecar file; [] if there is none.

    Raises
    ------
    IdentityError
        The file exists but is not a sidecar this version understands.
    """
    p = Path(path)
    if not p.exists():
        return []
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise IdentityError(f"{p}: the sidecar cannot be read ({exc}); move it away to start afresh "
                            "(every node then gets a new UUID)") from exc
    if not isinstance(data, dict) or data.get("format") != SIDECAR_FORMAT or not isinstance(data.get("nodes"), list):
        raise IdentityError(f"{p}: not a {SIDECAR_FORMAT} sidecar file")
    out = []
    try:
        for e in data["nodes"]:
            if not is_uuid(e["uuid"]):
                raise IdentityError(f"{p}: entry {e.get('path')!r} has an invalid uuid {e['uuid']!r}")
            sig = Signature.from_dict(e["signature"]) if e.get("signature") else None
            wc = tuple(float(x) for x in e["world_centroid"]) if e.get("world_centroid") else None
            out.append(_Entry(e["uuid"], str(e["path"]), str(e.get("name", "")), e.get("parent"), sig, wc,
                              bool(e.get("present", True))))
    except (KeyError, TypeError, ValueError) as exc:
        raise IdentityError(f"{p}: malformed sidecar entry ({exc})") from exc
    return out


def _world_centroid(doc: Document, index: int) -> tuple[float, float, float] | None:
    node = doc.nodes[index]
    if node.part is None:
        return None
    c = np.append(np.array(part_signature(doc, node.part).centroid), 1.0)
    w = doc.world_transform(index) @ c
    return (float(w[0]), float(w[1]), float(w[2]))


def assign_uuids(doc: Document, previous: list[_Entry] | None = None) -> dict[str, int]:
    """Give every node of ``doc`` a UUID (``Node.uuid``) and say how (``Node.match``).

    Parameters
    ----------
    doc : Document
        Modified in place.
    previous : list, optional
        Entries of the sidecar (:func:`load_sidecar`); None or [] on a first import.

    Returns
    -------
    dict of str to int
        How many nodes were matched each way (keys of :data:`MATCH_KINDS`).
    """
    previous = previous or []
    claimed: set[str] = set()
    for n in doc.nodes:
        n.uuid, n.match = None, None
    # 1. carried
    for n in doc.nodes:
        if n.carried_uuid is not None and is_uuid(n.carried_uuid) and n.carried_uuid.lower() not in claimed:
            n.uuid, n.match = n.carried_uuid.lower(), "carried"
            claimed.add(n.uuid)
    # 2. occurrence path
    by_path = {}
    for e in previous:
        by_path.setdefault(e.path, e)
    for n in doc.nodes:
        if n.uuid is None:
            e = by_path.get(n.path)
            if e is not None and e.uuid not in claimed:
                n.uuid, n.match = e.uuid, "path"
                claimed.add(e.uuid)
    # 3. geometric signature, nearest recorded world position among equal signatures
    with_sig = [e for e in previous if e.signature is not None]
    for n in doc.nodes:
        if n.uuid is None and n.part is not None and with_sig:
            sig = part_signature(doc, n.part)
            cands = [e for e in with_sig if e.uuid not in claimed and sig.matches(e.signature)]
            if cands:
                wc = np.array(_world_centroid(doc, n.index))
                best = min(cands, key=lambda e: (float(np.sum((np.array(e.world_centroid or wc) - wc) ** 2)),
                                                 e.path))
                n.uuid, n.match = best.uuid, "signature"
                claimed.add(best.uuid)
    # 4. assemblies by their children's former parent (deepest first: a renamed chain resolves upwards)
    parent_of = {e.uuid: e.parent for e in previous}
    for n in sorted(doc.nodes, key=lambda n: -n.path.count("/")):
        if n.uuid is None:
            votes: dict[str, int] = {}
            for c in doc.children(n.index):
                p = parent_of.get(c.uuid) if c.uuid else None
                if p is not None and p not in claimed:
                    votes[p] = votes.get(p, 0) + 1
            if votes:
                best_parent = max(sorted(votes), key=lambda k: votes[k])
                n.uuid, n.match = best_parent, "children"
                claimed.add(best_parent)
    # 5. new
    for n in doc.nodes:
        if n.uuid is None:
            n.uuid, n.match = str(uuidlib.uuid4()), "new"
    counts = dict.fromkeys(MATCH_KINDS, 0)
    for n in doc.nodes:
        counts[n.match] += 1
    return counts


def sidecar_entries(doc: Document, previous: list[_Entry] | None = None) -> list[dict]:
    """The sidecar content for ``doc`` (after :func:`assign_uuids`), keeping absent former entries."""
    out = []
    for n in doc.nodes:
        if n.uuid is None:
            raise IdentityError("assign_uuids must run before the sidecar is written", node=n.path)
        parent = doc.nodes[n.parent].uuid if n.parent is not None else None
        sig = part_signature(doc, n.part).as_dict() if n.part is not None else None
        wc = _world_centroid(doc, n.index)
        out.append({"uuid": n.uuid, "path": n.path, "name": n.name, "parent": parent, "signature": sig,
                    "world_centroid": list(wc) if wc else None, "present": True})
    current = {n.uuid for n in doc.nodes}
    for e in previous or []:
        if e.uuid not in current:
            out.append({"uuid": e.uuid, "path": e.path, "name": e.name, "parent": e.parent,
                        "signature": e.signature.as_dict() if e.signature else None,
                        "world_centroid": list(e.world_centroid) if e.world_centroid else None, "present": False})
    return out


def write_sidecar(path: str | Path, doc: Document, previous: list[_Entry] | None = None) -> Path:
    """Write the sidecar atomically (a crash never leaves half a file, which would lose every UUID)."""
    p = Path(path)
    data = {"format": SIDECAR_FORMAT, "document": doc.name, "length_unit": doc.length_unit,
            "nodes": sidecar_entries(doc, previous)}
    try:
        fd, tmp = tempfile.mkstemp(dir=p.parent, prefix=p.name + ".", suffix=".tmp")
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            json.dump(data, fh, indent=1)
        os.replace(tmp, p)
    except OSError as exc:
        raise IdentityError(f"{p}: cannot write the sidecar ({exc.strerror}); without it the UUIDs would not "
                            "survive the next import") from exc
    return p


def identify(doc: Document, sidecar: str | Path | None = None, write: bool = True) -> dict[str, int]:
    """Assign UUIDs from carried ids and the sidecar, then record them in the sidecar.

    Parameters
    ----------
    doc : Document
    sidecar : path, optional
        Default: ``<doc.source>.lumenlink.json`` (in the user's cache when the document's folder is
        read-only, see :func:`default_sidecar`); None and no source: no sidecar (carried UUIDs or new).
    write : bool
        Write the sidecar back.

    Returns
    -------
    dict of str to int
        Match counts, as :func:`assign_uuids`.
    """
    if sidecar is None and doc.source is not None:
        sidecar, warning = default_sidecar(doc.source)
        if warning:
            doc.warnings.append(warning)
    previous = load_sidecar(sidecar) if sidecar is not None else []
    counts = assign_uuids(doc, previous)
    if sidecar is not None and write:
        write_sidecar(sidecar, doc, previous)
    return counts
