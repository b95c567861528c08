"""The adapter's commands in the `lumenlink` command line: ``lumenlink push``, ``watch`` and ``freecad-addon``,
their options declared here once. `lumenlink.cli` adds them as installed plugins (the entry points of group
``lumenlink.commands`` in pyproject.toml), never by name, so the import runs one way: the adapter builds on lumenlink's
HTTP client, errors and shared options, and lumenlink's command line knows no adapter. Light to import (typer only):
the CAD stack loads when a command runs (`cad_adapter.cli`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from lumenlink.options import DEFAULT_SERVER, Angular, Linear, Relative, Server


def push(
    file: Annotated[Path, typer.Argument(help="STEP file, or FreeCAD document (.FCStd), to read.", exists=False)],
    scene: Annotated[str, typer.Option(help="Scene name; created if no scene has it.")],
    server: Server = DEFAULT_SERVER,
    linear: Linear = None,
    angular: Angular = None,
    relative: Relative = False,
    json_out: Annotated[bool, typer.Option("--json", help="Print the service's answer as JSON.")] = False,
    dry_run: Annotated[bool, typer.Option(
        "--dry-run", help="Print how each node was recognised and the diff the push would make; change nothing "
                          "(no upload, no sidecar, no scene).")] = False,
) -> None:
    """Read a CAD document, recognise its nodes in the scene, upload missing meshes and push its tree."""
    from cad_adapter import cli

    code = cli.push(file=file, scene=scene, server=server, linear=linear, angular=angular, relative=relative,
                    json_out=json_out, dry_run=dry_run)
    raise typer.Exit(code or 0)


def watch(
    file: Annotated[Path, typer.Argument(help="STEP file, or FreeCAD document (.FCStd), to watch.")],
    scene: Annotated[str, typer.Option(help="Scene name; created if no scene has it.")],
    server: Server = DEFAULT_SERVER,
    linear: Linear = None,
    angular: Angular = None,
    relative: Relative = False,
    debounce: Annotated[float, typer.Option(help="Seconds the file must stay unchanged.")] = 0.5,
) -> None:
    """Push the document again whenever the file changes (a live link)."""
    from cad_adapter import cli

    code = cli.watch(file=file, scene=scene, server=server, linear=linear, angular=angular, relative=relative,
                     debounce=debounce)
    raise typer.Exit(code or 0)


def freecad_addon(
    target: Annotated[Path | None, typer.Option(help="A FreeCAD Mod folder (default: FreeCAD's own, asked of "
                                                     "freecadcmd).")] = None,
) -> None:
    """Install the FreeCAD add-on (a LumenLink workbench: push, push on recompute or save, show light)."""
    from cad_adapter.errors import CadImportError
    from cad_adapter.freecad import install_addon

    try:
        where, version = install_addon(target)
    except (CadImportError, OSError) as exc:
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(2) from exc
    typer.echo(f"installed {where} (FreeCAD {version}); restart FreeCAD and choose the LumenLink workbench, or "
               f"push from a script: from lumenlink_freecad import link; link.push_now(App.ActiveDocument)")
