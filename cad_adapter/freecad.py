"""FreeCAD documents (.FCStd): identity from the CAD system itself, pushed through the same wire and REST calls.

FreeCAD runs in its own Python (Debian's ``freecad``, a headless ``freecadcmd``); the add-on's module
(`cad_adapter/freecad_mod/lumenlink_freecad/document.py`) reads the document there: its nodes, each node's UUID
from the object's ``LumenLinkUUID`` property (a new one where it has none, or is a copy), placements and FreeCAD's
own meshes. This side hashes the meshes, uploads what the service lacks and pushes the tree (`Pusher.push`),
then writes the UUIDs the push issued into the .FCStd (a second ``freecadcmd``), so that a reopened file gives the
same UUIDs and an empty diff. Nothing is written to the file when a push fails.

``lumenlink push model.FCStd`` and ``lumenlink watch model.FCStd`` come here (`cad_adapter.push.push_file`); the
add-on inside FreeCAD's GUI uses the same module (docs/guides/freecad.md).
"""

from __future__ import annotations

import base64
import json
import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from tracer.geometry_id import canonical_arrays, canonical_faces, hash_canonical

from .errors import CadImportError, TessellationError
from .tessellate import DEFAULT_ANGULAR, DEFAULT_LINEAR_MM, Mesh, Settings, Tessellation
from .tree import Document, Node, Part, assign_paths

#: the FreeCAD add-on's folder (a FreeCAD ``Mod``): its document module and the freecadcmd entry
MOD = Path(__file__).resolve().parent / "freecad_mod"
RUNNER = MOD / "lumenlink_run.py"
SUFFIXES = (".fcstd",)
#: what the add-on inside FreeCAD's GUI writes and hands to ``lumenlink push`` (`lumenlink_freecad.link`)
EXPORT_SUFFIX = ".lumenlink-freecad.json"
FORMAT = "lumenlink-freecad-1"
#: seconds one freecadcmd task may take (a large document's meshes)
TIMEOUT = 600.0


def is_freecad_file(path: Path) -> bool:
    """A FreeCAD document, or the add-on's export of one."""
    return Path(path).suffix.lower() in SUFFIXES or is_export(path)


def is_export(path: Path) -> bool:
    return Path(path).name.lower().endswith(EXPORT_SUFFIX)


def freecadcmd() -> str | None:
    """The headless FreeCAD: ``$LUMENLINK_FREECADCMD``, else ``freecadcmd`` or ``FreeCADCmd`` on the PATH."""
    named = os.environ.get("LUMENLINK_FREECADCMD")
    if named:
        return named if shutil.which(named) else None
    return shutil.which("freecadcmd") or shutil.which("FreeCADCmd")


def run_task(task: dict[str, Any], timeout: float = TIMEOUT) -> dict:
    """Run one task of `lumenlink_run.py` in freecadcmd; its answer. CadImportError saying why where FreeCAD is
    missing, fails, or answers an error."""
    cmd = freecadcmd()
    if cmd is None:
        raise CadImportError("FreeCAD is not installed here: a .FCStd file needs freecadcmd (Debian: apt-get install "
                             "freecad; or set LUMENLINK_FREECADCMD to its path)")
    with tempfile.TemporaryDirectory(prefix="lumenlink-freecad-") as tmp:
        task_file, out = Path(tmp) / "task.json", Path(tmp) / "out.json"
        task_file.write_text(json.dumps({**task, "out": str(out)}))
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
        env["LUMENLINK_FREECAD_TASK"] = str(task_file)
        try:
            proc = subprocess.run([cmd, str(RUNNER)], env=env, capture_output=True, text=True, timeout=timeout,
                                  cwd=tmp)
        except subprocess.TimeoutExpired as exc:
            raise CadImportError(f"FreeCAD took more than {timeout:.0f} s on {task.get('file')}") from exc
        if not out.exists():
            raise CadImportError(f"freecadcmd ended ({proc.returncode}) without an answer: "
                                 f"{(proc.stderr or proc.stdout)[-500:]}")
        answer = json.loads(out.read_text())
    if "error" in answer:
        raise CadImportError(answer["error"])
    return answer


def _array(text: str, dtype: str, columns: int | None) -> np.ndarray:
    a = np.frombuffer(base64.b64decode(text), dtype=np.dtype(dtype).newbyteorder("<"))
    return a.reshape(-1, columns) if columns else a


def mesh_of(part: dict, linear: float) -> Mesh:
    """A part of the export as the adapter's `Mesh` (canonical arrays, geometry id)."""
    v, f, n = canonical_arrays(_array(part["vertices"], "f8", 3), _array(part["triangles"], "u4", 3),
                               _array(part["normals"], "f8", 3))
    faces = canonical_faces(_array(part["face_ids"], "u4", None), len(f))
    return Mesh(v, f, n, hash_canonical(v, f, n, faces), linear, faces)


def document_of(export: dict, source: Path) -> tuple[Document, Tessellation]:
    """The export of `lumenlink_freecad.document.export` as the adapter's Document (UUIDs set, ``match``
    "freecad" or "freecad-new") and Tessellation."""
    if export.get("format") != FORMAT:
        raise CadImportError(f"{source}: the FreeCAD add-on answered format {export.get('format')!r}, not {FORMAT}")
    index = {n["uuid"]: i for i, n in enumerate(export["nodes"])}
    nodes = [Node(index=i, name=n["name"], parent=index[n["parent"]] if n["parent"] else None,
                  transform=np.asarray(n["transform"], dtype=np.float64).reshape(4, 4), part=n["part"],
                  uuid=n["uuid"], carried_uuid=None if n["issued"] else n["uuid"],
                  match="freecad-new" if n["issued"] else "freecad",
                  product=export["parts"][n["part"]]["name"] if n["part"] else "")
             for i, n in enumerate(export["nodes"])]
    parts = {key: Part(key, p["name"], None) for key, p in export["parts"].items()}
    issued = sum(1 for n in export["nodes"] if n["issued"])
    name = Path(export["file"]).name if export.get("file") else str(export.get("name") or source.name)
    doc = Document(name=name, length_unit=export["length_unit"], nodes=nodes, parts=parts, source=source,
                   warnings=list(export["warnings"]),
                   reconciliation={"source": "the FreeCAD document",
                                   "matched": {"freecad": len(nodes) - issued, "freecad-new": issued}},
                   reconciliation_detail={"issued": {n["object"]: n["uuid"] for n in export["nodes"]
                                                     if n["issued"]}})
    assign_paths(doc)
    linear = float(export["tessellation"]["linear"])
    tess = Tessellation(settings=Settings(linear, float(export["tessellation"]["angular"])))
    for key, p in export["parts"].items():
        if "empty" in p:
            tess.empty.append(key)
            tess.warnings.append(p["empty"])
        elif "error" in p:
            tess.failed[key] = p["error"]
        else:
            try:
                tess.meshes[key] = mesh_of(p, linear)
            except ValueError as exc:
                tess.failed[key] = f"FreeCAD's mesh is invalid: {exc}"
            tess.meshed += 1
    return doc, tess


def read_fcstd(path: Path, linear: float | None = None, angular: float | None = None
               ) -> tuple[Document, Tessellation, float]:
    """Read a .FCStd in freecadcmd: (Document, Tessellation, seconds). ``linear``: deflection in mm (default
    0.1), ``angular`` in radians (default 0.5). Nothing is written to the file."""
    path = Path(path)
    if not path.is_file():
        raise CadImportError(f"{path}: no such file")
    t = time.perf_counter()
    if is_export(path):   # the add-on meshed it already, at its own settings
        if linear is not None or angular is not None:
            raise TessellationError(f"{path.name} was meshed inside FreeCAD by the LumenLink add-on: its deflections "
                                    "are the add-on's settings, not --linear/--angular")
        try:
            export = json.loads(path.read_text())
        except (OSError, ValueError) as exc:
            raise CadImportError(f"{path}: not a LumenLink FreeCAD export ({exc})") from exc
        return _read(export, path, t)
    settings = Settings(DEFAULT_LINEAR_MM if linear is None else linear,
                        DEFAULT_ANGULAR if angular is None else angular)   # the adapter's checks and messages
    export = run_task({"action": "export", "file": str(path.resolve()), "linear": settings.linear,
                       "angular": settings.angular})
    return _read(export, path, t)


def _read(export: Any, path: Path, t: float) -> tuple[Document, Tessellation, float]:
    if not isinstance(export, dict):
        raise CadImportError(f"{path}: not a LumenLink FreeCAD export (a JSON object of format {FORMAT})")
    try:
        doc, tess = document_of(export, path)
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        if isinstance(exc, CadImportError):
            raise
        raise CadImportError(f"{path}: not a valid LumenLink FreeCAD export ({type(exc).__name__}: {exc})") from exc
    seconds = time.perf_counter() - t
    tess.seconds = seconds
    if not doc.nodes:
        raise CadImportError(f"{path}: the document shows no shape (hidden objects and sketches are not pushed)")
    return doc, tess, seconds


def stamp_fcstd(path: Path, doc: Document) -> int:
    """Write into the .FCStd the UUIDs its objects do not hold yet (those the push just issued); how many."""
    issued = doc.reconciliation_detail.get("issued") or {}
    if not issued:
        return 0
    return int(run_task({"action": "stamp", "file": str(Path(path).resolve()), "uuids": issued})["changed"])


def push_fcstd(file: Path, scene: str, server: str, linear: float | None = None, angular: float | None = None,
               relative: bool = False, *, transport: Any = None, dry_run: bool = False, on_read: Any = None,
               upload_progress: Any = None, token: str | None = None) -> tuple[Any, Any, Any, float, Any]:
    """`cad_adapter.push.push_file` for a .FCStd: read it in FreeCAD, push, and write the new UUIDs into the file
    (not on a dry run, not when the push fails). ``relative`` is refused: the deflections are absolute (mm,
    radians)."""
    from .client import Pusher

    if relative:
        raise TessellationError("a FreeCAD document is meshed with an absolute linear deflection in mm (--linear) "
                                "and an angular one (--angular); --relative does not apply to it")
    doc, tess, read_seconds = read_fcstd(file, linear, angular)   # a bad file says so before any service call
    with Pusher(server, transport=transport, token=token) as pusher:
        tree = pusher.scene_tree(scene)
    if on_read is not None:
        on_read(doc)
    with Pusher(server, transport=transport, upload_progress=upload_progress, token=token) as pusher:
        result = pusher.push(doc, tess, scene, base_revision=tree.revision if tree else None, dry_run=dry_run,
                             identity=False)
    if not dry_run and not is_export(file):   # the add-on stamps its own document
        stamped = stamp_fcstd(file, doc)
        if stamped:
            tess.warnings.append(f"{stamped} new UUID(s) written into {Path(file).name}")
    return result, doc, tess, read_seconds, tree.nodes if tree is not None else None


def install_addon(target: Path | None = None) -> tuple[Path, str]:
    """Install the add-on for FreeCAD's GUI: a link ``<FreeCAD's user folder>/Mod/LumenLink`` to `MOD` (or to
    ``target``/LumenLink). Answers (the link, FreeCAD's version). A folder of that name that is not our link is
    left alone (CadImportError saying so)."""
    version = "?"
    if target is None:
        where = run_task({"action": "where"})
        target, version = Path(where["user_dir"]) / "Mod", where["version"]
    link = Path(target) / "LumenLink"
    if link.is_symlink():
        link.unlink()
    elif link.exists():
        raise CadImportError(f"{link} exists and is not LumenLink's link to {MOD}: remove it, then install again")
    link.parent.mkdir(parents=True, exist_ok=True)
    link.symlink_to(MOD, target_is_directory=True)
    return link, version

