"""The options every command shares, declared once for the command line (typer): which service, which scene,
whether to create it, an element assignment, JSON output, a seed. Each command declares its own options in its
signature (`lumenlink.commands`, `commands_elements`, `commands_results`, `commands_luminance`); `lumenlink.cli`
registers the functions as they are. The tessellation options are push's and watch's."""

from __future__ import annotations

from typing import Annotated

import typer

DEFAULT_SERVER = "http://127.0.0.1:8000"

Server = Annotated[str, typer.Option(envvar="LUMENLINK_SERVER", help="Service URL (LUMENLINK_TOKEN is sent as the "
                                                                     "bearer token when set).")]
SceneOpt = Annotated[str, typer.Option(help="Scene name or id; a name no scene has is an error naming close ones.")]
Create = Annotated[bool, typer.Option("--create", help="Create the scene if no scene has that name.")]
Assignment = Annotated[str, typer.Argument(help="The element assignment: its id, or the node (path or UUID) that "
                                                "carries it.")]
JsonOut = Annotated[bool, typer.Option("--json", help="Print the answer as JSON.")]
Seed = Annotated[int, typer.Option(help="Same seed and revision: the same numbers.")]
Linear = Annotated[float | None, typer.Option(
    help="Linear deflection in document units (default 0.1 mm); with --relative a fraction of each part's size "
         "(default 0.002).")]
Angular = Annotated[float | None, typer.Option(help="Angular deflection, radians (default 0.5).")]
Relative = Annotated[bool, typer.Option(help="Linear deflection relative to each part's size.")]
