"""CAD adapter: STEP and cadquery documents → a UUID-stable tree of tessellated parts → the service.

Python API (the demo and the benchmark use it; the CLI is a thin shell around it)::

    import cad_adapter
    from cad_adapter.samples import car_assembly
    doc = cad_adapter.read_document("car.step")                 # or a cadquery.Assembly
    tess = cad_adapter.tessellate(doc, linear=0.1, angular=0.5)  # defaults: 0.1 mm, 0.5 rad
    body = cad_adapter.build_push(doc, tess, base_revision=3)    # docs/DESIGN.md's pushed tree (a dict)
    with cad_adapter.Pusher("http://127.0.0.1:8000") as p:
        result = p.push(doc, tess, scene="car")                  # result.answer: the service's diff

``doc.nodes[i].uuid`` / ``.match`` say which UUID each node got and how; ``tess.meshes[part]`` holds the
arrays and geometry id of each distinct part; :func:`cad_adapter.glb.encode_glb` encodes one.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from .errors import (
    CadAdapterError,
    CadImportError,
    EmptyDocumentError,
    IdentityError,
    PushError,
    RevisionConflict,
    ServiceUnavailable,
    TessellationError,
)
from .tessellate import Settings, Tessellation, TessellationCache
from .tree import Document, Node, Part

__all__ = [
    "CadAdapterError", "CadImportError", "EmptyDocumentError", "IdentityError", "PushError", "RevisionConflict",
    "ServiceUnavailable", "TessellationError", "Document", "Node", "Part", "Settings", "Tessellation",
    "TessellationCache", "read_document", "tessellate", "build_push", "Pusher",
]


def read_document(source: Any, *, sidecar: str | Path | None = None, write_sidecar: bool = True,
                  length_unit: str = "mm", name: str | None = None, previous: list[dict] | None = None,
                  previous_unit: str | None = None, tolerance: Any = None, reuse_geometry: bool = False) -> Document:
    """Read a STEP file or a cadquery assembly and give every node its UUID.

    Parameters
    ----------
    source : str, pathlib.Path or cadquery.Assembly
        A STEP file, or an in-memory assembly.
    sidecar : path, optional
        The identity sidecar. Default for a file: ``<file>.lumenlink.json``; for an assembly: none (the
        UUIDs then come from node metadata ``uuid``, else are new on every call).
    write_sidecar : bool
        Record the UUIDs in the sidecar.
    length_unit : str
        Unit of a cadquery assembly (a STEP file declares its own).
    name : str, optional
        Document name for an assembly (default: the root's name).
    previous, previous_unit, tolerance, reuse_geometry
        The scene's tree to recognise the nodes in (``Pusher.scene_tree(name).nodes``), its unit, the
        :class:`cad_adapter.identity.Tolerance` of "no change", and whether parts with the same B-rep keep
        the scene's geometry ids; see :func:`cad_adapter.identity.identify`.

    Returns
    -------
    Document
        Every node with ``uuid`` and ``match`` (one of ``cad_adapter.matching.RULES``); ``reconciliation``
        says how many nodes each rule matched and lists the ambiguous ones.
    """
    from .identity import identify

    if isinstance(source, str | Path):
        from .step_reader import read_step

        doc = read_step(source)
    else:
        import cadquery as cq

        if not isinstance(source, cq.Assembly):
            raise CadImportError(f"read_document takes a STEP path or a cadquery.Assembly, got {type(source).__name__}")
        from .assembly import read_assembly

        doc = read_assembly(source, length_unit=length_unit, name=name)
    identify(doc, sidecar, write=write_sidecar, previous=previous, previous_unit=previous_unit, tolerance=tolerance,
             reuse_geometry=reuse_geometry)
    return doc


def tessellate(doc: Document, linear: float | None = None, angular: float | None = None, relative: bool = False,
               cache: TessellationCache | None = None,
               progress: Callable[[int, int, str], None] | None = None) -> Tessellation:
    """Tessellate a document's distinct parts (see :mod:`cad_adapter.tessellate` for the defaults).

    Parameters
    ----------
    doc : Document
    linear : float, optional
        Chordal deflection in document units (default 0.1 mm), or with ``relative`` a fraction of each
        part's bounding-box diagonal (default 0.002).
    angular : float, optional
        Radians (default 0.5).
    relative : bool
    cache : TessellationCache, optional
    progress : callable(done, total, part_name), optional
    """
    from .tessellate import tessellate as _tessellate

    settings = Settings.default(doc.length_unit, linear, angular, relative)
    return _tessellate(doc, settings, cache=cache, progress=progress)


def build_push(doc: Document, tess: Tessellation, base_revision: int | None = None) -> dict:
    """docs/DESIGN.md's pushed tree for ``doc`` (see :func:`cad_adapter.payload.build_push`)."""
    from .payload import build_push as _build_push

    return _build_push(doc, tess, base_revision)


def __getattr__(name: str) -> Any:
    if name == "Pusher":  # httpx only when the client is used
        from .client import Pusher

        return Pusher
    raise AttributeError(name)
