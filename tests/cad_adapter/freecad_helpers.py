"""Helpers of the FreeCAD tests (tests/cad_adapter/test_freecad*.py): documents built and edited by a real
freecadcmd, and ``lumenlink push`` run as a user runs it."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

from cad_adapter import freecad

ROOT = Path(__file__).resolve().parents[2]
FREECAD = freecad.freecadcmd()
WHY = "FreeCAD is not installed (Debian: apt-get install freecad; `make test` does so where it runs as root)"
#: the objects of `LAMP` that are nodes (the hidden wheel, the sketch and the pad are not)
LAMP_NODES = {"Lamp", "Housing", "WheelLeft", "WheelRight", "Lens"}

PRELUDE = """
import sys, traceback
import FreeCAD as App, Part, Sketcher
try:
{body}
except Exception:
    traceback.print_exc()
    sys.exit(1)
sys.exit(0)
"""

LAMP = """
doc = App.newDocument("lamp")
lamp = doc.addObject("App::Part", "Lamp")
body = doc.addObject("PartDesign::Body", "Housing")
lamp.addObject(body)
sketch = body.newObject("Sketcher::SketchObject", "Sketch")
corners = [App.Vector(0, 0, 0), App.Vector(40, 0, 0), App.Vector(40, 20, 0), App.Vector(0, 20, 0)]
for i in range(4):
    sketch.addGeometry(Part.LineSegment(corners[i], corners[(i + 1) % 4]))
pad = body.newObject("PartDesign::Pad", "Pad")
pad.Profile = sketch
pad.Length = 10
wheel = doc.addObject("Part::Cylinder", "Wheel")
wheel.Radius, wheel.Height = 5, 3
wheel.Visibility = False          # the source of the two links: not itself in the scene
for name, y in (("WheelLeft", -10), ("WheelRight", 30)):
    link = doc.addObject("App::Link", name)
    link.LinkedObject = wheel
    link.Placement = App.Placement(App.Vector(20, y, 0), App.Rotation(App.Vector(1, 0, 0), 90))
lens = doc.addObject("Part::Sphere", "Lens")
lens.Radius = 4
lens.Placement.Base = App.Vector(20, 10, 30)
doc.recompute()
doc.saveAs(OUT)
"""


def run_freecad(code: str, **names: str) -> None:
    """Run ``code`` in a fresh freecadcmd, with ``names`` bound to strings (paths)."""
    bindings = "".join(f"{k} = {json.dumps(v)}\n" for k, v in names.items())
    script = Path(names.get("OUT", names.get("FILE", "/tmp"))).with_suffix(".freecad.py")
    script.write_text(PRELUDE.format(body=textwrap.indent(bindings + textwrap.dedent(code), "    ")))
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    r = subprocess.run([FREECAD, str(script)], capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]


def uuids_in_file(path: Path) -> dict[str, str]:
    """{object Label: LumenLinkUUID} as a fresh freecadcmd reads them from the saved file."""
    out = path.with_suffix(".uuids.json")
    run_freecad("""
        import json
        doc = App.openDocument(FILE)
        json.dump({o.Label: o.LumenLinkUUID for o in doc.Objects if "LumenLinkUUID" in o.PropertiesList},
                  open(RESULT, "w"))
    """, FILE=str(path), RESULT=str(out))
    return json.loads(out.read_text())


def push(*args: str, env_extra: dict | None = None) -> subprocess.CompletedProcess:
    env = {**os.environ, **(env_extra or {})}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    return subprocess.run([sys.executable, "-m", "lumenlink.cli", "push", *args], capture_output=True, text=True,
                          env=env, cwd=ROOT, timeout=600)


def pushed(file: Path, url: str, scene: str = "lamp") -> dict:
    r = push(str(file), "--scene", scene, "--server", url, "--json", "--linear", "0.2")
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


def lamp_file(folder: Path) -> Path:
    path = folder / "lamp.FCStd"
    run_freecad(LAMP, OUT=str(path))
    return path


def edited(lamp: Path, name: str, code: str) -> Path:
    """A copy of the lamp, opened in FreeCAD, edited by ``code`` (``doc`` is the document) and saved."""
    out = lamp.with_name(name)
    run_freecad("doc = App.openDocument(FILE)\n" + textwrap.dedent(code) + "\ndoc.recompute()\ndoc.saveAs(OUT)\n",
                FILE=str(lamp), OUT=str(out))
    return out
