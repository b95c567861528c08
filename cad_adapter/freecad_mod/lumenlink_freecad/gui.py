"""The add-on inside FreeCAD's GUI: its commands, the push that follows each recompute or save, the light shown back.

Pushes run one at a time in the background (`link.Push`: a child process), polled by a timer on the GUI thread, so
FreeCAD stays responsive; a request made while one runs waits for it, and requests closer together than the
settings' ``debounce_s`` make one push. Every outcome goes to the report view.
"""

from __future__ import annotations

import threading

import FreeCAD as App
import FreeCADGui as Gui
from PySide2 import QtCore, QtWidgets

from . import document, light, link

COMMANDS = ["LumenLink_Push", "LumenLink_ShowLight", "LumenLink_Settings"]


class LiveLink:
    """The background pusher: ``request(doc)`` starts a push after the debounce; ``outcomes`` keeps how each ended."""

    def __init__(self) -> None:
        self.debounce = QtCore.QTimer()
        self.debounce.setSingleShot(True)
        self.debounce.timeout.connect(self._start)
        self.poller = QtCore.QTimer()
        self.poller.setInterval(50)
        self.poller.timeout.connect(self._poll)
        self.running: link.Push | None = None
        self.pending = None
        self.outcomes: list[link.Outcome] = []
        #: the export each document was last pushed with (its meshes are what the service's results refer to)
        self.pushed: dict[str, dict] = {}

    def request(self, doc, delay_s: float | None = None) -> None:
        self.pending = doc
        delay = link.Settings.load().debounce_s if delay_s is None else delay_s
        if self.running is None:
            self.debounce.start(int(1000 * delay))

    def _start(self) -> None:
        doc, self.pending = self.pending, None
        if doc is None or self.running is not None:
            return
        settings = link.Settings.load()
        problems = settings.problems()
        if problems:
            self._done(link.Outcome(False, "LumenLink: cannot push: " + "; ".join(problems)))
            return
        try:
            self.running = link.Push(doc, settings)
        except Exception as exc:   # an export FreeCAD refuses, a command that does not start
            self._done(link.Outcome(False, f"LumenLink: push failed before it started: {exc}"))
            return
        self.poller.start()

    def _poll(self) -> None:
        outcome = self.running.poll() if self.running is not None else None
        if outcome is None:
            return
        self.poller.stop()
        if outcome.ok:
            self.pushed[self.running.doc.Name] = self.running.export
        self.running = None
        self._done(outcome)
        if self.pending is not None:
            self.debounce.start(0)

    def _done(self, outcome: link.Outcome) -> None:
        self.outcomes.append(outcome)
        (App.Console.PrintMessage if outcome.ok else App.Console.PrintError)(outcome.message + "\n")


LINK: LiveLink | None = None
#: Show light's runs in progress, and the legends it painted (or {"error": why}), newest last
RUNNING: set = set()
LEGENDS: list[dict] = []
OBSERVERS: list = []    # FreeCAD keeps a weak hold on its observers


class Observer:
    """Pushes after each recompute or save, as the settings' ``push_on`` says."""

    def slotRecomputedDocument(self, doc) -> None:  # noqa: N802 (FreeCAD's name)
        if link.Settings.load().push_on == "recompute" and LINK is not None:
            LINK.request(doc)

    def slotFinishSaveDocument(self, doc, path) -> None:  # noqa: N802
        if link.Settings.load().push_on == "save" and LINK is not None:
            LINK.request(doc)


def show_light(doc, sensor: str) -> dict:
    """Simulate the surface sensor (for the settings' ``light_seconds``), colour ``doc``'s faces by its answer and
    put its legend over the 3D view, waiting here (scripts; the command does it in the background); answers the
    legend (`light.face_colours`). Raises `light.ServiceError` or ValueError, saying why."""
    settings = link.Settings.load()
    export = pushed_export(doc, settings)
    result = light.simulate_surface(settings, settings.scene or doc.Label, sensor, settings.light_seconds)
    return paint(doc, export, result, sensor)


def pushed_export(doc, settings: link.Settings) -> dict:
    """The export ``doc`` was last pushed with in this session (the meshes the service's answer is about), else the
    document exported now (pushed before, from the command line or another session)."""
    pushed = LINK.pushed.get(doc.Name) if LINK is not None else None
    return pushed if pushed is not None else document.export(doc, settings.linear, settings.angular)


def paint(doc, export: dict, result: dict, sensor: str) -> dict:
    """Colour ``doc``'s faces by a surface sensor's answer over ``export`` (the document as it was pushed)."""
    colours, legend = light.face_colours(export, result)
    for name, faces in colours.items():
        obj = doc.getObject(name)
        if obj is None or obj.ViewObject is None:
            continue
        if document.is_link(obj):
            obj.ViewObject.setElementColors({f"Face{i + 1}": c for i, c in enumerate(faces)})
            continue
        obj.ViewObject.DiffuseColor = list(faces)
        tip = getattr(obj, "Tip", None)   # a PartDesign Body is drawn by its tip feature (same faces, same order)
        if tip is not None and tip.ViewObject is not None:
            tip.ViewObject.DiffuseColor = list(faces)
    _legend_label(light.legend_html(legend, sensor))
    App.Console.PrintMessage(f"LumenLink: {sensor}: {legend['low']:,.0f} to {legend['high']:,.0f} lx over "
                             f"{legend['faces']} faces, +- {legend['stderr']:,.0f} lx\n")
    LEGENDS.append(legend)
    return legend


class LightInBackground:
    """Show light without freezing FreeCAD: the simulation (an HTTP call of up to ``light_seconds``) in a thread,
    the painting on the GUI thread once it answered."""

    def __init__(self, doc, sensor: str) -> None:
        settings = link.Settings.load()
        self.doc, self.sensor = doc, sensor
        self.export = pushed_export(doc, settings)
        self.answer: dict = {}
        scene = settings.scene or doc.Label
        self.thread = threading.Thread(target=self._simulate, args=(settings, scene), daemon=True)
        self.thread.start()
        self.timer = QtCore.QTimer()
        self.timer.setInterval(100)
        self.timer.timeout.connect(self._poll)
        self.timer.start()
        App.Console.PrintMessage(f"LumenLink: simulating {sensor} for up to {settings.light_seconds:g} s\n")

    def _simulate(self, settings, scene: str) -> None:
        try:
            self.answer["result"] = light.simulate_surface(settings, scene, self.sensor, settings.light_seconds)
        except (light.ServiceError, ValueError) as exc:
            self.answer["error"] = str(exc)

    def _poll(self) -> None:
        if self.thread.is_alive():
            return
        self.timer.stop()
        RUNNING.discard(self)
        try:
            if "error" in self.answer:
                raise ValueError(self.answer["error"])
            paint(self.doc, self.export, self.answer["result"], self.sensor)
        except ValueError as exc:
            App.Console.PrintError(f"LumenLink: cannot show the light: {exc}\n")
            LEGENDS.append({"error": str(exc)})


def _legend_label(html: str) -> None:
    area = Gui.getMainWindow().findChild(QtWidgets.QMdiArea)
    window = area.activeSubWindow() if area is not None else None
    if window is None:
        return
    label = window.widget().findChild(QtWidgets.QLabel, "LumenLinkLegend")
    if label is None:
        label = QtWidgets.QLabel(window.widget())
        label.setObjectName("LumenLinkLegend")
        label.setStyleSheet("background: rgba(255, 255, 255, 220); padding: 6px; border: 1px solid #888;")
    label.setText(html)
    label.adjustSize()
    label.move(12, 12)
    label.show()


class PushCommand:
    def GetResources(self) -> dict:  # noqa: N802
        return {"MenuText": "Push to LumenLink", "ToolTip": "Push this document's tree and meshes to the LumenLink "
                                                             "scene (UUIDs are kept in the document)"}

    def IsActive(self) -> bool:  # noqa: N802
        return App.ActiveDocument is not None

    def Activated(self) -> None:  # noqa: N802
        LINK.request(App.ActiveDocument, 0.0)


class ShowLightCommand:
    def GetResources(self) -> dict:  # noqa: N802
        return {"MenuText": "Show light", "ToolTip": "Colour the parts by a surface sensor's illuminance"}

    def IsActive(self) -> bool:  # noqa: N802
        return App.ActiveDocument is not None

    def Activated(self) -> None:  # noqa: N802
        settings = link.Settings.load()
        sensor, ok = settings.light_sensor, True
        if not sensor:
            sensor, ok = QtWidgets.QInputDialog.getText(None, "LumenLink", "Surface sensor (name or id):")
        if ok and sensor:
            try:
                RUNNING.add(LightInBackground(App.ActiveDocument, sensor))
            except ValueError as exc:
                App.Console.PrintError(f"LumenLink: cannot show the light: {exc}\n")


class SettingsCommand:
    def GetResources(self) -> dict:  # noqa: N802
        return {"MenuText": "LumenLink settings", "ToolTip": "Service, scene, token, deflections, automatic push"}

    def Activated(self) -> None:  # noqa: N802
        SettingsDialog().exec_()


class SettingsDialog(QtWidgets.QDialog):
    """The settings as a form; refused with the reason while they are wrong."""

    def __init__(self) -> None:
        super().__init__(Gui.getMainWindow())
        self.setWindowTitle("LumenLink settings")
        s = link.Settings.load()
        form = QtWidgets.QFormLayout(self)
        self.edits = {name: QtWidgets.QLineEdit(str(getattr(s, name))) for name in ("server", "scene", "token",
                                                                                       "command", "light_sensor")}
        self.edits["token"].setEchoMode(QtWidgets.QLineEdit.Password)
        self.numbers = {name: QtWidgets.QLineEdit(str(getattr(s, name))) for name in ("linear", "angular",
                                                                                        "debounce_s", "light_seconds")}
        self.push_on = QtWidgets.QComboBox()
        self.push_on.addItems(list(link.PUSH_ON))
        self.push_on.setCurrentText(s.push_on)
        for name, widget in [*self.edits.items(), *self.numbers.items(), ("push_on", self.push_on)]:
            form.addRow(name.replace("_", " "), widget)
        buttons = QtWidgets.QDialogButtonBox(QtWidgets.QDialogButtonBox.Ok | QtWidgets.QDialogButtonBox.Cancel)
        buttons.accepted.connect(self.accept)
        buttons.rejected.connect(self.reject)
        form.addRow(buttons)

    def accept(self) -> None:
        try:
            numbers = {k: float(e.text()) for k, e in self.numbers.items()}
            s = link.Settings(**{k: e.text() for k, e in self.edits.items()}, **numbers,
                              push_on=self.push_on.currentText())
        except ValueError as exc:
            QtWidgets.QMessageBox.warning(self, "LumenLink", f"not a number: {exc}")
            return
        problems = s.problems()
        if problems:
            QtWidgets.QMessageBox.warning(self, "LumenLink", "\n".join(problems))
            return
        s.save()
        super().accept()


def register() -> None:
    """Commands and the observer, once per FreeCAD session."""
    global LINK
    if LINK is not None:
        return
    LINK = LiveLink()
    OBSERVERS.append(Observer())
    App.addDocumentObserver(OBSERVERS[-1])
    Gui.addCommand("LumenLink_Push", PushCommand())
    Gui.addCommand("LumenLink_ShowLight", ShowLightCommand())
    Gui.addCommand("LumenLink_Settings", SettingsCommand())
