"""FreeCAD's live link beside the STEP path, on the demo car rebuilt in FreeCAD (issue 56).

The sample car (`cad_adapter.samples.car_assembly`) is rebuilt as a FreeCAD document: each part's B-rep (written by
cadquery as BREP, read by FreeCAD's ``Part.read``) a ``Part::Feature`` with its placement, each sub-assembly an
``App::Part`` (FreeCAD 0.20's own STEP importer crashes headless on it). Against a real service process:

1. ``lumenlink push car.FCStd`` (the command line: freecadcmd reads the document, the push, the UUIDs written back)
   beside ``lumenlink push car.step`` (the same model as FreeCAD's STEP export): a first push into a new scene, and a
   push of the unchanged document. Wall seconds of the whole command, medians of ``repeat`` runs.
2. The live link as the add-on runs it (`lumenlink_freecad.link.Push` in freecadcmd: the export inside FreeCAD, then
   ``lumenlink push`` of it): from the recompute after an edit to the service's answer, for a door moved (a placement)
   and the lens reshaped (one part's geometry). The peer: the same edit exported to STEP by FreeCAD and pushed with
   ``lumenlink push`` (the export itself not counted). Medians of ``repeat`` edits.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]

BUILD = """
import json, sys, traceback
import FreeCAD as App, Part
try:
    spec = json.load(open(SPEC))
    doc = App.newDocument("car")
    made = []
    for n in spec:
        if n["brep"]:
            obj = doc.addObject("Part::Feature", n["name"])
            obj.Shape = Part.read(n["brep"])
        else:
            obj = doc.addObject("App::Part", n["name"])
        obj.Label = n["name"]
        obj.Placement = App.Placement(App.Matrix(*n["matrix"]))
        if n["parent"] is not None:
            made[n["parent"]].addObject(obj)
        made.append(obj)
    doc.recompute()
    doc.saveAs(OUT)
except Exception:
    traceback.print_exc()
    sys.exit(1)
"""

LIVE = """
import json, sys, time, traceback
sys.path.insert(0, MOD)
import FreeCAD as App, Import
from lumenlink_freecad import link
try:
    doc = App.openDocument(FILE)
    settings = link.Settings(server=SERVER, scene=SCENE, command=COMMAND, linear=0.1, angular=0.5)
    first = link.Push(doc, settings).wait()
    assert first.ok, first.message
    door = next(o for o in doc.Objects if o.Label == "door_left")
    lens = next(o for o in doc.Objects if o.Label == "lens")
    rows = []
    for k in range(REPEAT):
        for case in ("door_moved", "lens_reshaped"):
            if case == "door_moved":
                door.Placement.Base = door.Placement.Base + App.Vector(0, 0, 1.0)
            else:
                shape = lens.Shape.copy()
                shape.scale(1.01, lens.Shape.BoundBox.Center)
                lens.Shape = shape
            doc.recompute()
            t0 = time.perf_counter()
            outcome = link.Push(doc, settings).wait()
            seconds = time.perf_counter() - t0
            assert outcome.ok, outcome.message
            step = f"{OUTDIR}/{case}_{k}.step"
            Import.export([o for o in doc.Objects if not o.InList], step)
            rows.append({"case": case, "seconds": seconds, "step": step, "message": outcome.message,
                         "blas_built": outcome.answer.get("blas_built")})
    json.dump(rows, open(REPORT, "w"))
except Exception:
    traceback.print_exc()
    sys.exit(1)
"""


def _freecad(code: str, **names: Any) -> None:
    from cad_adapter.freecad import freecadcmd

    folder = Path(names.get("OUTDIR") or tempfile.gettempdir())
    script = folder / f"bench-freecad-{os.getpid()}-{time.monotonic_ns()}.py"
    script.write_text("".join(f"{k} = {json.dumps(v)}\n" for k, v in names.items()) + code)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    r = subprocess.run([freecadcmd(), str(script)], capture_output=True, text=True, timeout=1800, env=env)
    if r.returncode != 0:
        raise RuntimeError(f"freecadcmd failed: {r.stdout[-2000:]}{r.stderr[-2000:]}")


def car_spec(folder: Path) -> list[dict]:
    """The sample car as a flat list (parents first): name, parent index, 4x4 placement (row-major, mm), BREP."""
    import cadquery as cq

    from cad_adapter.samples import car_assembly

    spec: list[dict] = []

    def walk(assy: Any, parent: int | None) -> None:
        t = assy.loc.wrapped.Transformation()
        matrix = [t.Value(r, c) for r in range(1, 4) for c in range(1, 5)] + [0, 0, 0, 1]
        brep = None
        if assy.obj is not None:
            shapes = [v for v in assy.obj.vals() if isinstance(v, cq.Shape)]
            brep = str(folder / f"{len(spec)}_{assy.name}.brep")
            cq.Compound.makeCompound(shapes).exportBrep(brep)
        spec.append({"name": assy.name, "parent": parent, "matrix": matrix, "brep": brep})
        here = len(spec) - 1
        for child in assy.children:
            walk(child, here)

    walk(car_assembly(), None)
    return spec


def _cli(*args: str) -> float:
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "lumenlink.cli", "push", *args, "--json"], capture_output=True,
                       text=True, cwd=ROOT, timeout=1800)
    seconds = time.perf_counter() - t0
    if r.returncode != 0:
        raise RuntimeError(f"lumenlink push {args[0]} failed: {r.stderr[-1500:]}")
    return seconds


def run(quick: bool = False) -> dict:
    from cad_adapter.freecad import MOD, freecadcmd

    if freecadcmd() is None:
        return {"skipped": "FreeCAD is not installed", "markdown": "Not run: FreeCAD is not installed here."}
    sys.path.insert(0, str(ROOT / "tests"))
    from service_process import running_service

    repeat = 2 if quick else 3
    out: dict[str, Any] = {"repeat": repeat}
    with tempfile.TemporaryDirectory(prefix="bench-freecad-") as tmp:
        folder = Path(tmp)
        car = folder / "car.FCStd"
        _freecad(BUILD, SPEC=str(_write(folder / "spec.json", car_spec(folder))), OUT=str(car), OUTDIR=str(folder))
        step = folder / "car.step"
        _freecad("import FreeCAD as App, Import\ndoc = App.openDocument(FILE)\n"
                 "Import.export([o for o in doc.Objects if not o.InList], OUT)\n", FILE=str(car), OUT=str(step),
                 OUTDIR=str(folder))
        with running_service(folder / "service") as url:
            _cli(str(step), "--scene", "warm-up", "--server", url)   # the service's first push compiles its builders
            cli: dict[str, dict[str, list[float]]] = {"first_push": {"freecad": [], "step": []},
                                                      "unchanged": {"freecad": [], "step": []}}
            for k in range(repeat):
                for label, path in (("freecad", car), ("step", step)):
                    cli["first_push"][label].append(_cli(str(path), "--scene", f"{label}-{k}", "--server", url))
                    cli["unchanged"][label].append(_cli(str(path), "--scene", f"{label}-{k}", "--server", url))
            out["cli"] = {case: {label: statistics.median(v) for label, v in d.items()} for case, d in cli.items()}
            report = folder / "live.json"
            _cli(str(step), "--scene", "car-step", "--server", url)
            _freecad(LIVE, MOD=str(MOD), FILE=str(car), SERVER=url, SCENE="car-live",
                     COMMAND=str(Path(sys.executable).with_name("lumenlink")), REPEAT=repeat, OUTDIR=str(folder),
                     REPORT=str(report))
            rows = json.loads(report.read_text())
            for row in rows:
                row["step_seconds"] = _cli(row["step"], "--scene", "car-step", "--server", url)
            out["live"] = {case: {"freecad": statistics.median(r["seconds"] for r in rows if r["case"] == case),
                                  "step": statistics.median(r["step_seconds"] for r in rows if r["case"] == case),
                                  "blas_built": [r["blas_built"] for r in rows if r["case"] == case]}
                           for case in ("door_moved", "lens_reshaped")}
    out["markdown"] = _markdown(out)
    return out


def _write(path: Path, data: Any) -> Path:
    path.write_text(json.dumps(data))
    return path


def _markdown(out: dict) -> str:
    lines = ["The demo car rebuilt in FreeCAD 0.20 (BREP parts, App::Part sub-assemblies) against a real service "
             "process; wall seconds, medians of " f"{out['repeat']} runs, beside the same model pushed as STEP "
             "(FreeCAD's export, read by the STEP adapter). `lumenlink bench --only freecad`.", "",
             "| push | FreeCAD | STEP | FreeCAD / STEP |", "| --- | ---: | ---: | ---: |"]
    names = {"first_push": "`lumenlink push` into a new scene", "unchanged": "`lumenlink push`, nothing changed",
             "door_moved": "live link: a door moved, recompute to answer", "lens_reshaped":
             "live link: the lens reshaped, recompute to answer"}
    for group in ("cli", "live"):
        for case, r in out[group].items():
            lines.append(f"| {names[case]} | {r['freecad']:.2f} | {r['step']:.2f} | {r['freecad'] / r['step']:.2f} |")
    lines += ["", "The live link's rows: the add-on's own path (the export inside FreeCAD, then `lumenlink push` of "
              "it), against pushing the STEP file FreeCAD exported after the same edit (the export's own time not "
              "counted). Bottom levels built per edit: door " f"{out['live']['door_moved']['blas_built']}, lens "
              f"{out['live']['lens_reshaped']['blas_built']}."]
    return "\n".join(lines)
