"""The add-on inside FreeCAD's GUI (a real FreeCAD 0.20 under Xvfb, a real service; issue 56): installed by
`cad_adapter.freecad.install_addon` into a throw-away home, its workbench's Push command pushes the open document,
a recompute pushes it again by itself (``push_on`` = recompute) and the report view says what the service did; Show
light colours the housing's faces by a surface sensor's illuminance (viridis from the smallest face mean to the
largest, with a legend), and a screenshot of it goes to ``$LUMENLINK_ARTIFACTS/freecad``. A push to a service that
is down says so and writes no UUID into the document. Skipped, saying why, without FreeCAD or Xvfb."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

import numpy as np
import pytest
from freecad_helpers import FREECAD, WHY, lamp_file, pushed, uuids_in_file

from cad_adapter.freecad import install_addon

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests"))

from service_process import free_port, running_service  # noqa: E402

from lumenlink import Client  # noqa: E402

GUI = shutil.which("freecad") or shutil.which("FreeCAD")
XVFB = shutil.which("xvfb-run")
pytestmark = [pytest.mark.skipif(FREECAD is None or GUI is None, reason=WHY),
              pytest.mark.skipif(XVFB is None, reason="Xvfb is not installed (Debian: apt-get install xvfb; "
                                                      "`make test` does so where it runs as root)"),
              pytest.mark.slow]
ARTIFACTS = Path(os.environ.get("LUMENLINK_ARTIFACTS") or Path(tempfile.gettempdir()) / "lumenlink-artifacts")
ARTIFACTS = ARTIFACTS / "freecad"

USER_CFG = """<?xml version="1.0" encoding="UTF-8" standalone="no" ?>
<FCParameters><FCParamGroup Name="Root"><FCParamGroup Name="BaseApp"><FCParamGroup Name="Preferences">
<FCParamGroup Name="General"><FCText Name="AutoloadModule">PartWorkbench</FCText></FCParamGroup>
<FCParamGroup Name="Mod"><FCParamGroup Name="LumenLink">
<FCText Name="server">{server}</FCText><FCText Name="command">{command}</FCText>
<FCText Name="push_on">recompute</FCText>
<FCFloat Name="debounce_s" Value="0.2"/><FCFloat Name="linear" Value="0.2"/><FCFloat Name="light_seconds" Value="3"/>
<FCText Name="light_sensor">housing</FCText>
</FCParamGroup></FCParamGroup></FCParamGroup></FCParamGroup></FCParamGroup></FCParameters>
"""

# Runs in FreeCAD's GUI: each step after the last one's push has ended (the event loop must turn for the add-on's
# timers); the report goes to REPORT, the screenshot to SHOT.
SESSION = """
import json, os, traceback
import FreeCAD as App, FreeCADGui as Gui
from PySide2 import QtCore
from lumenlink_freecad import gui, link

doc = App.openDocument(FILE)
for name in ("Lamp", "Housing", "Pad", "WheelLeft", "WheelRight", "Lens"):
    doc.getObject(name).ViewObject.Visibility = True   # a document saved by freecadcmd has no view settings
report = {"outcomes": [], "steps": []}

def finish():
    report["outcomes"] = [{"ok": o.ok, "message": o.message, "answer": o.answer} for o in gui.LINK.outcomes]
    json.dump(report, open(REPORT, "w"))
    os._exit(0)

def after(ready, then, waited=0):
    if ready() or waited > 1200:
        step(then)
    else:
        QtCore.QTimer.singleShot(100, lambda: after(ready, then, waited + 1))

def after_push(count, then):
    after(lambda: len(gui.LINK.outcomes) >= count, then)

def step(fn):
    try:
        report["steps"].append(fn.__name__)
        fn()
    except Exception:
        report["error"] = traceback.format_exc()
        finish()

def push_from_the_workbench():
    Gui.runCommand("LumenLink_Push")
    after_push(1, show_the_light)

def show_the_light():
    Gui.runCommand("LumenLink_ShowLight")      # the sensor named in the settings, simulated in the background
    after(lambda: gui.LEGENDS, painted)

def painted():
    report["legend"] = gui.LEGENDS[-1]
    report["colours"] = [list(c)[:3] for c in doc.getObject("Housing").ViewObject.DiffuseColor]
    view = Gui.ActiveDocument.ActiveView
    view.viewIsometric()
    view.fitAll()
    QtCore.QTimer.singleShot(800, lambda: step(screenshot))

def screenshot():
    from PIL import ImageGrab
    ImageGrab.grab(xdisplay=os.environ["DISPLAY"]).save(SHOT)
    doc.getObject("Pad").Length = 12
    doc.recompute()                       # push_on = recompute: the add-on pushes by itself
    after_push(2, push_to_a_service_that_is_down)

def push_to_a_service_that_is_down():
    App.ParamGet(link.PARAMS).SetString("server", DOWN)
    copy = doc.copyObject(doc.getObject("Lens"))
    report["copy"] = copy.Name
    Gui.runCommand("LumenLink_Push")
    after_push(3, check_the_copy)

def check_the_copy():
    report["copy_owner"] = getattr(doc.getObject(report["copy"]), "LumenLinkOwner", None)
    Gui.runCommand("LumenLink_ShowLight")      # the service is still down
    after(lambda: len(gui.LEGENDS) > 1, light_from_a_service_that_is_down)

def light_from_a_service_that_is_down():
    report["light_down"] = gui.LEGENDS[-1]
    finish()

Gui.activateWorkbench("LumenLinkWorkbench")
QtCore.QTimer.singleShot(500, lambda: step(push_from_the_workbench))
"""


def test_the_workbench_pushes_on_recompute_and_shows_the_light(tmp_path) -> None:
    home = tmp_path / "home"
    install_addon(home / ".local" / "share" / "FreeCAD" / "Mod")
    lamp = lamp_file(tmp_path)
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    shot = ARTIFACTS / "lamp-light.png"
    shot.unlink(missing_ok=True)
    with running_service(tmp_path / "service") as url:
        pushed(lamp, url)                   # by the command line first: the UUIDs are in the file
        uuids = uuids_in_file(lamp)
        with Client(url) as ll:
            ll.assign("lamp", uuids["Housing"], {"type": "lambertian", "reflectance": 0.8})
            ll.assign("lamp", uuids["Lens"], {"type": "dielectric", "ior": 1.5})
            ll.add_light("lamp", {"type": "point", "position": [0.02, 0.01, 0.06], "intensity_cd": 1000})
            ll.add_sensor("lamp", {"type": "surface", "node": uuids["Housing"], "name": "housing"})
        cfg, script, report = tmp_path / "user.cfg", tmp_path / "session.py", tmp_path / "report.json"
        cfg.write_text(USER_CFG.format(server=url, command=Path(sys.executable).with_name("lumenlink")))
        bindings = {"FILE": str(lamp), "REPORT": str(report), "SHOT": str(shot),
                    "DOWN": f"http://127.0.0.1:{free_port()}"}
        script.write_text("".join(f"{k} = {json.dumps(v)}\n" for k, v in bindings.items())
                          + textwrap.dedent(SESSION))
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
        env.update(HOME=str(home), QTWEBENGINE_CHROMIUM_FLAGS="--no-sandbox")
        r = subprocess.run([XVFB, "-a", "-s", "-screen 0 1280x1024x24", GUI, "-u", str(cfg), str(script)],
                           capture_output=True, text=True, timeout=300, env=env)
        assert report.exists(), r.stdout[-3000:] + r.stderr[-3000:]
        got = json.loads(report.read_text())
    assert "error" not in got, got["error"]
    first, recomputed, down = got["outcomes"]
    assert first["ok"] and "unchanged 5" in first["message"], first      # the file was pushed already: no diff
    assert recomputed["ok"] and "changed 1" in recomputed["message"], (recomputed, uuids)
    assert "bottom levels built 1" in recomputed["message"]
    assert not down["ok"] and "cannot be reached" in down["message"], down
    # the copy carries the lens's properties as FreeCAD copied them: a failed push stamped no UUID of its own on it
    assert got["copy_owner"] == "Lens" and got["copy"] != "Lens"
    assert "cannot be reached" in got["light_down"]["error"], got["light_down"]
    legend = got["legend"]
    assert legend["faces"] == 6 and 0 <= legend["low"] < legend["high"]   # the box's six faces; the bottom is dark
    assert len(got["colours"]) == 6 and len({tuple(c) for c in got["colours"]}) > 1
    from PIL import Image

    image = Image.open(shot).convert("RGB")
    model = image.crop((0, 330, image.width, image.height - 300))   # below the legend, above the report view
    top = max(got["colours"], key=lambda c: c[1])        # the brightest face's colour: viridis' yellow end
    assert top[0] > 2 * top[2] and top[1] > 2 * top[2], top
    # the top face shows that colour, shaded by the view's light (darker, the same hue): no grey part, no blue
    # background, is yellow
    r, g, b = np.asarray(model, dtype=float).transpose(2, 0, 1)
    yellow = int(((r > 100) & (g > 100) & (b < 0.5 * np.minimum(r, g))).sum())
    assert yellow > 5000, yellow
