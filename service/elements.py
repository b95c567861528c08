"""Optical elements with an inside: the library of prepared models, and putting them onto a scene's parts.

The library (``POST /elements``) is shared by every scene and outlives restarts: a row per element in the
``elements`` table (its checked body and summary) and its prepared arrays in ``<data_dir>/elements/<id>.npz``,
written before the row, so a row always has its file. The same body gives the same id, and preparing it again is
never needed: a second scene, or a restarted service, loads the file (`ElementLibrary.get`).

An assignment (``POST /scenes/{id}/elements``: ``{"element", "node", "facing" | "faces"}``) is stored like a light
(`service.store.TABLES`, orphaned with its node) and applied to the tracer scene by `sync`, after every change of the
tree or of the assignments: the node's instance becomes the tracer's relief kind (`tracer.Scene.set_element`), keeping
its instance id, transform and material. A node carries several elements on supports that share no triangle (dots
underneath a light guide, prisms on top); one whose support overlaps another's is refused (409). A support that a push
made unusable (no longer planar, say) is no failed push: the assignment stays, inactive, and says why (`problems`).

A grating (``{"type": "grating", ...}``, `tracer.elements.grating`, issue 52) is solved by RCWA when posted: its body
is checked and its cost bounded first (a 422, nothing stored), then it is prepared in the request and kept like the
others (its table as ``<id>.npz``, the same bytes for the same body). Assigned to a face like any element, it goes
onto the plain support and scatters by its table of orders (`tracer.elements.diffraction`): the scene turns spectral
(the answer's ``effect_reasons`` says why), and an answer whose photons met it where the table ran out says so in
its ``warnings``.
"""

from __future__ import annotations

import dataclasses
import os
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from sqlalchemy import Engine, insert, select

from service import db
from service.errors import Invalid, NotFound
from tracer.geometry_id import is_geometry_id


class ElementLibrary:
    """Prepared elements by id: in the database and their files, and in memory once used."""

    def __init__(self, engine: Engine, directory: Path, meshes: Any = None) -> None:
        self.engine = engine
        self.directory = directory
        self.meshes = meshes   # the service's `service.meshes.MeshStore`: a feature may be a pushed mesh
        self._models: dict[str, Any] = {}
        self._tables: dict[tuple[str, float], Any] = {}
        self._lock = threading.Lock()

    def _file(self, eid: str) -> Path:
        return self.directory / f"{eid}.npz"

    def create(self, body: Any) -> tuple[dict[str, Any], bool]:
        """Prepare `body` (422 naming the field where it cannot be) and keep it; answers its summary and whether
        it is new (an element of the same body is answered as it is, prepared nothing)."""
        from tracer.elements import ElementError, prepare

        if isinstance(body, dict) and body.get("type") == "grating":
            return self._create_grating(body)
        try:
            model = prepare(self._with_pushed_mesh(body))
        except ElementError as exc:
            raise Invalid(str(exc)) from None
        known = self._row(model.id)
        if known is not None:
            return _summary(known), False
        self.directory.mkdir(parents=True, exist_ok=True)
        tmp = self.directory / f".{model.id}.{os.getpid()}.{threading.get_ident()}.npz"
        arrays: dict[str, Any] = model.arrays()
        np.savez(tmp, **arrays)
        os.replace(tmp, self._file(model.id))
        s = model.summary()
        with self.engine.begin() as conn:
            if conn.execute(select(db.elements.c.id).where(db.elements.c.id == model.id)).first() is None:
                conn.execute(insert(db.elements).values(id=model.id, body=model.body, features=s["features"],
                                                        bytes=s["bytes"], prepare_seconds=s["prepare_seconds"]))
        with self._lock:
            self._models[model.id] = model
        return s, True

    def _with_pushed_mesh(self, body: Any) -> Any:
        """`body` with a feature given as a pushed mesh (``{"geometry": "<gid>"}``, DESIGN.md: a geometry pushed by
        ``PUT /geometries/{gid}``, in mm) read into ``{"shape": "mesh", "vertices_mm", "triangles"}``
        (`tracer.elements.shapes.mesh`); 422 where it names no pushed geometry. The element keeps the mesh itself,
        so the same mesh is the same element however it came."""
        feature = body.get("feature") if isinstance(body, dict) else None
        if not isinstance(feature, dict) or "geometry" not in feature:
            return body
        if set(feature) != {"geometry"}:
            raise Invalid(f"feature: a pushed mesh is {{'geometry': '<gid>'}} alone; got also "
                          f"{sorted(set(feature) - {'geometry'})}"[:300])
        gid = feature["geometry"]
        if not isinstance(gid, str) or not is_geometry_id(gid):
            raise Invalid(f"feature.geometry must be a geometry id (64 lowercase hex characters), got {gid!r}"[:300])
        if self.meshes is None or not self.meshes.has(gid):
            raise Invalid(f"feature.geometry {gid} is not pushed: PUT /geometries/{gid} first (its mesh in mm)")
        mesh = self.meshes.load(gid)
        return {**body, "feature": {"shape": "mesh", "vertices_mm": mesh.vertices.astype(np.float64).tolist(),
                                    "triangles": mesh.triangles.astype(np.int64).tolist()}}

    def _create_grating(self, body: dict) -> tuple[dict[str, Any], bool]:
        """A grating: checked and its cost bounded (422, nothing stored), answered as it is where the library holds
        its body already (nothing solved), else solved (`tracer.elements.grating.prepare`, in this request) and
        kept: its table's bytes as ``<id>.npz``, then its row."""
        canon, known = self.check_grating(body)
        if known is not None:
            return known, False
        return self.solve_grating(canon), True

    def check_grating(self, body: dict) -> tuple[dict, dict[str, Any] | None]:
        """A grating body checked and its cost bounded (422 naming the field, nothing stored): its canonical body,
        and its summary where the library holds it already (None where it must be solved)."""
        from tracer.elements import ElementError, grating

        try:
            canon = grating.check(body)
            grating.affordable(canon)
        except ElementError as exc:
            raise Invalid(str(exc)) from None
        known = self._row(grating.element_id(canon))
        return canon, (None if known is None else _summary(known))

    def solve_grating(self, canon: dict, progress: Callable[[float], None] | None = None) -> dict[str, Any]:
        """Solve a checked grating body (`check_grating`), `progress(fraction)` after each table point, and keep it:
        its table's bytes as ``<id>.npz``, then its row; answers its summary."""
        from tracer.elements import ElementError, grating

        eid = grating.element_id(canon)
        try:
            table = grating.prepare(canon, progress=progress)
        except ElementError as exc:
            raise Invalid(str(exc)) from None
        self.directory.mkdir(parents=True, exist_ok=True)
        tmp = self.directory / f".{eid}.{os.getpid()}.{threading.get_ident()}.npz"
        tmp.write_bytes(table.to_bytes())
        os.replace(tmp, self._file(eid))
        s = table.summary()
        with self.engine.begin() as conn:
            if conn.execute(select(db.elements.c.id).where(db.elements.c.id == eid)).first() is None:
                conn.execute(insert(db.elements).values(id=eid, body=table.body, features=None, bytes=s["bytes"],
                                                        prepare_seconds=s["prepare_seconds"]))
        with self._lock:
            self._models[eid] = table
        return s

    def _row(self, eid: str) -> Any:
        with self.engine.connect() as conn:
            return conn.execute(select(db.elements).where(db.elements.c.id == eid)).first()

    def summary(self, eid: str) -> dict[str, Any]:
        """The element's summary with its body; 404 where the library has none of that id."""
        row = self._row(eid)
        if row is None:
            raise NotFound(f"no element {eid} in the library (POST /elements first)")
        return {**_summary(row), "body": row.body}

    def list(self) -> list[dict[str, Any]]:
        with self.engine.connect() as conn:
            return [_summary(r) for r in conn.execute(select(db.elements).order_by(db.elements.c.created_at,
                                                                                   db.elements.c.id))]

    def get(self, eid: str) -> Any:
        """The prepared model (`tracer.elements.Microstructure`, or a grating's `tracer.elements.grating.GratingTable`),
        from memory or its file: never prepared again."""
        with self._lock:
            if eid in self._models:
                return self._models[eid]
        row = self._row(eid)
        if row is None:
            raise NotFound(f"no element {eid} in the library (POST /elements first)")
        from tracer.elements import Microstructure

        if _kind(row) == "grating":
            from tracer.elements.grating import GratingTable

            model: Any = GratingTable.from_bytes(self._file(eid).read_bytes(), float(row.prepare_seconds))
        else:
            with np.load(self._file(eid)) as arrays:
                model = Microstructure.from_arrays(arrays)
        with self._lock:
            self._models[eid] = model
        return model

    def bsdf(self, eid: str, ior: float) -> Any:
        """The element's tabulated BSDF on a solid of index `ior` (`tracer.elements.bsdf.tabulate`), with its error
        measured against the exact model (`tracer.elements.bsdf.model_error`): computed once from its exact model and
        kept beside it (``<id>.bsdf-<ior>.npz``), then read back, never computed again (a table kept before its error
        was measured gets it measured once, and is kept again)."""
        from tracer.elements.bsdf import Table, model_error, tabulate

        key = (eid, float(ior))
        with self._lock:
            if key in self._tables:
                return self._tables[key]
        path = self.directory / f"{eid}.bsdf-{float(ior)!r}.npz"
        table, kept = None, False
        if path.exists():
            with np.load(path) as arrays:
                table = Table.from_arrays(arrays)
            kept = table.error is not None
        if table is None:
            table = tabulate(self.get(eid), float(ior))
        elif not kept:   # kept before its error was measured
            table = dataclasses.replace(table, error=model_error(self.get(eid), table))
        if not kept:
            self.directory.mkdir(parents=True, exist_ok=True)
            tmp = self.directory / f".{eid}.bsdf.{os.getpid()}.{threading.get_ident()}.npz"
            saved: dict[str, Any] = table.arrays()
            np.savez(tmp, **saved)
            os.replace(tmp, path)
        with self._lock:
            self._tables[key] = table
        return table

    def keep_record(self, eid: str, suffix: str, record: dict[str, Any] | bytes) -> None:
        """Keep how element `eid` was made, beside its file: a pack's record (``.pack.json``) and picture
        (``.pack.png``), a design loop's (``.design.json``, ``.design.png``); a dict is kept as JSON."""
        import json

        data = json.dumps(record).encode() if isinstance(record, dict) else record
        tmp = self.directory / f".{eid}{suffix}.{os.getpid()}.{threading.get_ident()}"
        tmp.write_bytes(data)
        os.replace(tmp, self.directory / f"{eid}{suffix}")

    def record(self, eid: str, suffix: str) -> bytes:
        """What `keep_record` kept for element `eid` under `suffix`; 404 where the element was not made that way."""
        self.summary(eid)
        path = self.directory / f"{eid}{suffix}"
        if not path.exists():
            how = "a design loop (POST /elements/{id}/design" if suffix.startswith(".design") else \
                "a pack (POST /elements/{id}/pack"
            raise NotFound(f"element {eid} was not made by {how} makes one)")
        return path.read_bytes()

    def loaded(self) -> set[str]:
        """Ids held in memory (what `get` will not read again)."""
        with self._lock:
            return set(self._models)


def _kind(row: Any) -> str:
    """The element's type, from its stored body ('microstructure' or 'grating')."""
    body = row.body if isinstance(row.body, dict) else {}
    return str(body.get("type", "microstructure"))


def _summary(row: Any) -> dict[str, Any]:
    kind = _kind(row)
    out = {"id": row.id, "type": kind, "features": row.features, "bytes": int(row.bytes),
           "prepare_seconds": float(row.prepare_seconds)}
    if kind == "grating":
        from tracer.elements.grating import SOLVER

        out["solver"] = SOLVER
    return out


GRATING_MODEL = ("is a grating: it scatters by its table of orders (the wave solution); 'model' chooses between a "
                 "microstructure's exact features and its tabulated BSDF: leave it out, or give 'exact'")


def check_assignment(body: dict, library: ElementLibrary, state: Any) -> None:
    """422 for an assignment the scene cannot take: an element the library lacks, a node that is missing or has
    no geometry of its own."""
    try:
        summary = library.summary(body["element"])
    except NotFound as exc:
        raise Invalid(f"element: {exc.detail}") from None
    if summary["type"] == "grating" and body.get("model", "exact") != "exact":
        raise Invalid(f"model: element {body['element']} {GRATING_MODEL}")
    if not state.has_node(body["node"]):
        raise Invalid(f"node: no node {body['node']} in scene {state.id}", node=body["node"])
    if body["node"] not in state.instances:
        raise Invalid(f"node: {body['node']} has no geometry of its own: an element goes onto a part's faces",
                      node=body["node"])


NO_IOR = ("model: a tabulated BSDF ('bsdf') is computed for the part's material, which must be a dielectric with a "
          "number ior: assign one first, or use 'exact'")


def check_support(body: dict, state: Any) -> None:
    """422 where the node's part cannot carry the element (after `check_assignment`): its `facing` or `faces` select
    no plane of the part's mesh, or a 'bsdf' model has no dielectric ior to be computed for. Reads the
    mesh only (the tracer's own `support` checks, lengths in the document's unit); changes nothing."""
    from tracer.elements import ElementError
    from tracer.elements import support as sup

    gid = state.tracer.instance_geometry(state.instances[body["node"]])
    vertices, triangles, _ = state.tracer.geometry_arrays(gid)
    ids = state.face_ids.get(gid)
    try:
        prims = sup.select(vertices, triangles, facing=body.get("facing"), faces=body.get("faces"),
                           face_ids=None if ids is None else np.asarray(ids))
        sup.frame(vertices, triangles, prims, state.tree.scale * 1000.0)
        if body.get("model") == "bsdf" and _ior(state, body["node"]) is None:
            raise ElementError(NO_IOR)
    except ElementError as exc:
        raise Invalid(f"the element cannot go onto node {body['node']}: {exc}", node=body["node"]) from None


def _ior(state: Any, node: str) -> float | None:
    """The index of the node's effective material (its own, else its nearest ancestor's) where it is a dielectric
    with a number ior; None otherwise."""
    tree = state.tree
    u: str | None = node
    while u is not None:
        m = state.materials.get(u)
        if m is not None:
            ior = m.get("ior") if m.get("type") == "dielectric" else None
            return float(ior) if isinstance(ior, int | float) and not isinstance(ior, bool) else None
        i = tree.index.get(u)
        u = tree.parents[i] if i is not None else None
    return None


def sync(state: Any, library: ElementLibrary) -> None:
    """Make the tracer scene's elements those of ``state.elements`` on the nodes present (call before commit):
    an element is put on (keyed by its assignment id: a part carries one per support) where its node's instance does
    not carry it yet, taken off where it no longer applies. Where a support cannot carry it, ``state.element_problems
    [aid]`` says why (and ``state.element_taken[aid]`` names the assignment whose support it overlaps) and the part
    stays as it was."""
    want = {}
    for aid, body in state.elements.items():
        inst = state.instances.get(body["node"])
        if inst is not None:
            want[aid] = inst
    alive = set(state.instances.values())
    for aid, inst in list(state.element_instances.items()):
        if want.get(aid) != inst:
            if inst in alive:
                state.tracer.set_element(inst, None, key=aid)
            del state.element_instances[aid]
    mm = state.tree.scale * 1000.0
    from tracer.elements import ElementError
    from tracer.elements.checks import SupportTaken

    for aid, inst in want.items():
        body = state.elements[aid]
        ior = _ior(state, body["node"]) if body.get("model") == "bsdf" else None
        if state.element_instances.get(aid) == inst and state.element_ior.get(aid) == ior:
            continue
        try:
            table = None
            if body.get("model") == "bsdf":
                if ior is None:
                    raise ElementError(NO_IOR)
                table = library.bsdf(body["element"], ior)
            state.tracer.set_element(inst, library.get(body["element"]), facing=body.get("facing"),
                                     faces=body.get("faces"), mm_per_unit=mm, table=table, key=aid,
                                     face_ids=state.face_ids.get(state.tracer.instance_geometry(inst)))
        except (ElementError, NotFound) as exc:
            state.element_problems[aid] = str(getattr(exc, "detail", exc))
            if isinstance(exc, SupportTaken):
                state.element_taken[aid] = exc.key
            if state.element_instances.pop(aid, None) is not None:
                state.tracer.set_element(inst, None, key=aid)
            continue
        state.element_instances[aid] = inst
        state.element_ior[aid] = ior
        state.element_model_error[aid] = None if table is None else table.error
        state.element_problems.pop(aid, None)
        state.element_taken.pop(aid, None)


def public(state: Any, aid: str, body: dict) -> dict[str, Any]:
    """An assignment as listed: its body, whether its node is gone, whether it is applied and if not why."""
    inst = state.element_instances.get(aid)
    return {"id": aid, "body": body, "orphaned": not state.has_node(body["node"]),
            "applied": inst is not None, "problem": state.element_problems.get(aid),
            "model": body.get("model", "exact"),
            "support": None if inst is None else state.tracer.element_support(inst, key=aid)}


def describe(state: Any) -> list[dict[str, Any]]:
    """The elements applied in the scene, as an answer names them: assignment id, element id, node, model, and for
    a tabulated BSDF its ``model_error`` (`tracer.elements.bsdf.model_error`, per side: the worst probe beam's
    deviation of the transmitted share from the exact model's, with its standard error)."""
    out = []
    for aid in sorted(state.element_instances):
        body = state.elements[aid]
        entry = {"id": aid, "element": body["element"], "node": body["node"], "model": body.get("model", "exact")}
        if entry["model"] == "bsdf" and state.element_model_error.get(aid) is not None:
            entry["model_error"] = state.element_model_error[aid]
        out.append(entry)
    return out
