"""``freecadcmd`` entry of `cad_adapter.freecad`: one task on one .FCStd file, in FreeCAD's own Python.

The task is the JSON file named by ``LUMENLINK_FREECAD_TASK``: ``{"action": "export", "file", "out", "linear",
"angular"}``
writes `lumenlink_freecad.document.export` of the document to ``out``; ``{"action": "stamp", "file", "out",
"uuids": {object Name: UUID}}`` writes the UUIDs into the document's objects and saves it where any changed.
``{"action": "where"}`` answers FreeCAD's user data folder (its ``Mod`` holds add-ons) and version.
``out`` always receives a JSON object: the answer, or ``{"error": why}``; the exit code is 0 or 1 (freecadcmd
itself answers 0 for an uncaught exception, so nothing is left to it).
"""

import json
import os
import sys
import traceback

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))


def run(task: dict) -> dict:
    import FreeCAD as App
    from lumenlink_freecad import document

    if task["action"] == "where":   # where this FreeCAD looks for add-ons (lumenlink freecad-addon)
        return {"user_dir": App.getUserAppDataDir(), "version": ".".join(App.Version()[:3])}
    path = task["file"]
    if not os.path.isfile(path):
        return {"error": f"{path}: no such file"}
    try:
        doc = App.openDocument(path)
    except Exception as exc:   # FreeCAD raises its own kinds for a file it cannot read
        return {"error": f"{path}: FreeCAD cannot open it as a document ({type(exc).__name__}: {exc})"}
    try:
        if task["action"] == "export":
            return document.export(doc, float(task["linear"]), float(task["angular"]))
        if task["action"] == "stamp":
            changed = document.stamp(doc, task["uuids"])
            if changed:
                doc.save()
            return {"changed": changed}
        return {"error": f"unknown action {task['action']!r}"}
    finally:
        App.closeDocument(doc.Name)


def main() -> int:
    task = json.load(open(os.environ["LUMENLINK_FREECAD_TASK"]))
    try:
        answer = run(task)
    except Exception as exc:
        answer = {"error": f"{type(exc).__name__}: {exc}", "traceback": traceback.format_exc()}
    with open(task["out"], "w") as out:
        json.dump(answer, out)
    return 1 if "error" in answer else 0


sys.exit(main())
