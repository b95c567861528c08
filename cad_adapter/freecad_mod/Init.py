# LumenLink's FreeCAD add-on (a FreeCAD Mod folder): nothing to set up without the GUI. `lumenlink push model.FCStd`
# runs lumenlink_run.py in freecadcmd itself; the GUI's workbench is in InitGui.py.
