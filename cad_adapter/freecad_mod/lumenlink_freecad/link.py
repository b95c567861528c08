"""The live link's core, without Qt: settings, one push of the open document, and the line the report view shows.

A push exports the document here, in FreeCAD (`document.export`: nodes, UUIDs, FreeCAD's meshes), and hands the
export to the ``lumenlink`` command (``lumenlink push <doc>.lumenlink-freecad.json``), which hashes the meshes,
uploads what the service lacks and pushes the tree through the same REST calls as every other push. The UUIDs it
issued are written into the document's objects only once the push succeeded; a failed push leaves the document as
it was and says why. The GUI (`gui`) runs it in the background; ``wait`` runs it to the end (scripts, tests).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass, fields

import FreeCAD as App

from . import document

PARAMS = "User parameter:BaseApp/Preferences/Mod/LumenLink"
EXPORT_SUFFIX = ".lumenlink-freecad.json"
#: when the add-on pushes by itself: never, after each recompute, after each save
PUSH_ON = ("off", "recompute", "save")


@dataclass
class Settings:
    """What the add-on needs to reach LumenLink, kept in FreeCAD's parameters (``PARAMS``)."""

    server: str = "http://127.0.0.1:8000"
    scene: str = ""          # '' : the document's label
    token: str = ""          # '' : $LUMENLINK_TOKEN, where set
    command: str = ""        # the lumenlink executable; '' : the one on the PATH
    linear: float = 0.1      # mm
    angular: float = 0.5     # rad
    push_on: str = "off"
    debounce_s: float = 1.0
    light_seconds: float = 5.0   # the budget of Show light's simulation
    light_sensor: str = ""       # the surface sensor Show light shows; '' : asked each time

    @classmethod
    def load(cls) -> Settings:
        group = App.ParamGet(PARAMS)
        values = {}
        for f in fields(cls):
            default = f.default
            if isinstance(default, float):
                values[f.name] = group.GetFloat(f.name, default)
            else:
                values[f.name] = group.GetString(f.name, default)
        return cls(**values)

    def save(self) -> None:
        group = App.ParamGet(PARAMS)
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, float):
                group.SetFloat(f.name, value)
            else:
                group.SetString(f.name, str(value))

    def problems(self) -> list[str]:
        """What is wrong with these settings, in words; [] where nothing is."""
        out = []
        if not self.server.startswith(("http://", "https://")):
            out.append(f"the server must be an http(s) URL, got {self.server!r}")
        if self.linear <= 0 or self.angular <= 0 or self.angular > 1.5708:
            out.append(f"deflections must be > 0 (linear {self.linear} mm, angular {self.angular} rad <= pi/2)")
        if self.debounce_s < 0 or self.light_seconds <= 0:
            out.append(f"debounce_s must be >= 0 and light_seconds > 0 (got {self.debounce_s}, {self.light_seconds})")
        if self.push_on not in PUSH_ON:
            out.append(f"push_on must be one of {', '.join(PUSH_ON)}, got {self.push_on!r}")
        if self.executable() is None:
            out.append(f"the lumenlink command was not found ({self.command or 'lumenlink on the PATH'}): install "
                       "LumenLink (make serve's .venv/bin/lumenlink) and name it in the settings")
        return out

    def executable(self) -> str | None:
        return shutil.which(self.command or "lumenlink")


@dataclass
class Outcome:
    """How a push ended: ``ok``, the line for the report view, the service's answer (pushes that succeeded)."""

    ok: bool
    message: str
    answer: dict | None = None


def report(answer: dict, scene: str, seconds: float) -> str:
    """One line: what the service did with the push, and how long it took from the export to its answer."""
    lists = (("moved", "moved"), ("geometry_changed", "changed"), ("added", "added"), ("removed", "removed"),
             ("renamed", "renamed"))
    diff = ", ".join(f"{word} {len(answer.get(key) or [])}" for key, word in lists)
    line = (f"LumenLink: scene {scene!r} revision {answer.get('base_revision')} -> {answer.get('revision')}: {diff}, "
            f"unchanged {answer.get('unchanged', 0)}; bottom levels built {answer.get('blas_built', 0)}; "
            f"{seconds * 1e3:.0f} ms")
    orphaned = answer.get("orphaned") or []
    if orphaned:
        line += f"; {len(orphaned)} assignment(s) orphaned (kept: they come back with their node)"
    return line


def failure(stderr: str, code: int) -> str:
    """The ``lumenlink`` command's own message (its last error lines), with what its exit code means."""
    meaning = {2: "bad input", 3: "the service cannot be reached", 4: "the scene changed meanwhile: push again"}
    lines = [s.strip() for s in stderr.strip().splitlines() if s.strip()]
    said = " ".join(lines[-3:]) if lines else "no message"
    return f"LumenLink: push failed ({meaning.get(code, f'exit {code}')}): {said}"


class Push:
    """One push of ``doc``, started at once: the export here, ``lumenlink push`` in a child process."""

    def __init__(self, doc, settings: Settings) -> None:
        self.doc = doc
        self.scene = settings.scene or doc.Label
        self.started = time.monotonic()
        self.export = document.export(doc, settings.linear, settings.angular)
        self.folder = tempfile.mkdtemp(prefix="lumenlink-freecad-")
        path = os.path.join(self.folder, doc.Name + EXPORT_SUFFIX)
        with open(path, "w") as out:
            json.dump(self.export, out)
        # FreeCAD's own Python paths are not the lumenlink command's
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
        if settings.token:
            env["LUMENLINK_TOKEN"] = settings.token
        command = settings.executable() or settings.command or "lumenlink"
        # its output to files: a pipe that nobody reads while the push runs would stop a child with a long answer
        self.out, self.err = (open(os.path.join(self.folder, name), "w+") for name in ("stdout", "stderr"))
        self.proc = subprocess.Popen([command, "push", path, "--scene", self.scene, "--server", settings.server,
                                      "--json"], stdout=self.out, stderr=self.err, text=True, env=env)

    def poll(self) -> Outcome | None:
        """None while the push runs; then how it ended (the UUIDs it issued are then in the document)."""
        if self.proc.poll() is None:
            return None
        out, err = (self._read(f) for f in (self.out, self.err))
        shutil.rmtree(self.folder, ignore_errors=True)
        if self.proc.returncode != 0:
            return Outcome(False, failure(err, self.proc.returncode))
        try:
            answer = json.loads(out)
        except ValueError:
            return Outcome(False, f"LumenLink: the lumenlink command answered no JSON: {out[-300:]!r}")
        issued = {n["object"]: n["uuid"] for n in self.export["nodes"] if n["issued"] and n["object"]}
        line = report(answer, self.scene, time.monotonic() - self.started)
        try:
            document.stamp(self.doc, issued)
        except Exception as exc:   # the document was closed meanwhile
            line += f"; the {len(issued)} new UUID(s) could not be written into the document ({exc})"
        return Outcome(True, line, answer)

    @staticmethod
    def _read(file) -> str:
        file.seek(0)
        text = file.read()
        file.close()
        return text

    def wait(self, timeout: float = 600.0) -> Outcome:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            outcome = self.poll()
            if outcome is not None:
                return outcome
            time.sleep(0.05)
        self.proc.kill()
        return Outcome(False, f"LumenLink: the push took more than {timeout:.0f} s and was stopped")


def push_now(doc, settings: Settings | None = None) -> Outcome:
    """Push ``doc`` and wait for the answer (scripts, ``freecadcmd``); prints the outcome to the report view."""
    settings = settings or Settings.load()
    problems = settings.problems()
    if problems:
        outcome = Outcome(False, "LumenLink: cannot push: " + "; ".join(problems))
    else:
        outcome = Push(doc, settings).wait()
    (App.Console.PrintMessage if outcome.ok else App.Console.PrintError)(outcome.message + "\n")
    return outcome
