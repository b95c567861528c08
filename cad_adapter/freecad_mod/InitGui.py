# LumenLink's workbench: push the open document to a LumenLink service, push again after each recompute or save
# (its settings), and show a surface sensor's illuminance on the parts. Installed by `lumenlink freecad-addon`.
import FreeCADGui as Gui


class LumenLinkWorkbench(Gui.Workbench):
    MenuText = "LumenLink"
    ToolTip = "Keep a LumenLink light simulation in step with this document"

    def Initialize(self):
        from lumenlink_freecad import gui

        gui.register()
        self.appendToolbar("LumenLink", gui.COMMANDS)
        self.appendMenu("LumenLink", gui.COMMANDS)

    def GetClassName(self):
        return "Gui::PythonWorkbench"


def _start():
    # the automatic push follows the documents whatever workbench is active
    from lumenlink_freecad import gui

    gui.register()


Gui.addWorkbench(LumenLinkWorkbench())
_start()
