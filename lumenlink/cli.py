"""The `lumenlink` command: one subcommand per job, each importing its package only when run.

Importing the CAD stack or numba costs seconds, so `lumenlink --help` imports neither.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Annotated, Any

import typer

app = typer.Typer(
    help="LumenLink: keep a light simulation in step with a CAD model.",
    no_args_is_help=True,
    add_completion=False,
)


def _call(module: str, function: str, issue: int, **kwargs: Any) -> Any:
    """Run `module.function(**kwargs)`, or say clearly which part is not built yet."""
    try:
        mod = importlib.import_module(module)
        fn = getattr(mod, function)
    except (ImportError, AttributeError) as exc:
        typer.echo(f"lumenlink: {module}.{function} is not built yet (issue {issue}): {exc}", err=True)
        raise typer.Exit(2) from exc
    return fn(**kwargs)


@app.command()
def serve(
    host: Annotated[str, typer.Option(envvar="LUMENLINK_HOST", help="Address to listen on.")] = "127.0.0.1",
    port: Annotated[int, typer.Option(envvar="LUMENLINK_PORT", help="TCP port.")] = 8000,
    data_dir: Annotated[
        Path, typer.Option(envvar="LUMENLINK_DATA_DIR", help="SQLite file, meshes and BLAS cache.")
    ] = Path("./var"),
    warm: Annotated[bool, typer.Option(
        envvar="LUMENLINK_WARM_KERNELS",
        help="Compile the light-transport kernels in the background from the start, so that the first query "
             "does not wait for them (GET /health says when they are ready).")] = True,
    token: Annotated[str | None, typer.Option(
        envvar="LUMENLINK_TOKEN", help="Bearer token every request must carry (Authorization: Bearer …); "
                                       "required with a --host beyond loopback.")] = None,
    dask: Annotated[str | None, typer.Option(
        envvar="LUMENLINK_DASK_SCHEDULER", help="Run the photon batches on the Dask cluster whose scheduler is at "
                                                "this address (tcp://host:8786); the answers are the same.")] = None,
    device: Annotated[str, typer.Option(
        envvar="LUMENLINK_DEVICE", help="auto, cpu or cuda: auto takes a CUDA GPU where numba-cuda finds one, "
                                        "cuda without one stops here (exit 2). On CUDA the photon batches run on "
                                        "the card (a scene that does not fit: on the CPU, saying why); answers say "
                                        "where (`device`).")] = "auto",
) -> None:
    """Start the REST service (uvicorn)."""
    _call("service.server", "run", 5, host=host, port=port, data_dir=data_dir, warm=warm, token=token, dask=dask,
          device=device)


@app.command()
def push(
    file: Annotated[Path, typer.Argument(help="STEP file, or FreeCAD document (.FCStd), to read.", exists=False)],
    scene: Annotated[str, typer.Option(help="Scene name; created if no scene has it.")],
    server: Annotated[str, typer.Option(envvar="LUMENLINK_SERVER", help="Service URL.")] = "http://127.0.0.1:8000",
    linear: Annotated[float | None, typer.Option(
        help="Linear deflection in document units (default 0.1 mm); with --relative a fraction of each part's "
             "size (default 0.002).")] = None,
    angular: Annotated[float | None, typer.Option(help="Angular deflection, radians (default 0.5).")] = None,
    relative: Annotated[bool, typer.Option(help="Linear deflection relative to each part's size.")] = False,
    json_out: Annotated[bool, typer.Option("--json", help="Print the service's answer as JSON.")] = False,
    dry_run: Annotated[bool, typer.Option(
        "--dry-run", help="Print how each node was recognised and the diff the push would make; change nothing "
                          "(no upload, no sidecar, no scene).")] = False,
) -> None:
    """Read a CAD document, recognise its nodes in the scene, upload missing meshes and push its tree."""
    code = _call(
        "cad_adapter.cli", "push", 4, file=file, scene=scene, server=server, linear=linear,
        angular=angular, relative=relative, json_out=json_out, dry_run=dry_run,
    )
    raise typer.Exit(code or 0)


@app.command()
def watch(
    file: Annotated[Path, typer.Argument(help="STEP file, or FreeCAD document (.FCStd), to watch.")],
    scene: Annotated[str, typer.Option(help="Scene name; created if no scene has it.")],
    server: Annotated[str, typer.Option(envvar="LUMENLINK_SERVER", help="Service URL.")] = "http://127.0.0.1:8000",
    linear: Annotated[float | None, typer.Option(
        help="Linear deflection in document units (default 0.1 mm); with --relative a fraction of each part's "
             "size (default 0.002).")] = None,
    angular: Annotated[float | None, typer.Option(help="Angular deflection, radians (default 0.5).")] = None,
    relative: Annotated[bool, typer.Option(help="Linear deflection relative to each part's size.")] = False,
    debounce: Annotated[float, typer.Option(help="Seconds the file must stay unchanged.")] = 0.5,
) -> None:
    """Push the document again whenever the file changes (a live link)."""
    code = _call(
        "cad_adapter.cli", "watch", 4, file=file, scene=scene, server=server, linear=linear,
        angular=angular, relative=relative, debounce=debounce,
    )
    raise typer.Exit(code or 0)


@app.command("freecad-addon")
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


# ---------------------------------------------------------------- the engineer's loop (issue 22)
# Built on lumenlink.Client; exit codes as push: 2 bad usage (options, files, a URL without its scheme, an unknown
# scene or node path, a body the service refuses), 3 the service unreachable, 1 anything else.

Server = Annotated[str, typer.Option(envvar="LUMENLINK_SERVER", help="Service URL (LUMENLINK_TOKEN is sent as the "
                                                                     "bearer token when set).")]
SceneOpt = Annotated[str, typer.Option(help="Scene name or id; a name no scene has is an error naming close ones.")]
Create = Annotated[bool, typer.Option("--create", help="Create the scene if no scene has that name.")]


@app.command()
def nodes(
    scene: SceneOpt,
    server: Server = "http://127.0.0.1:8000",
    create: Create = False,
    json_out: Annotated[bool, typer.Option("--json", help="Print the nodes as JSON.")] = False,
) -> None:
    """Print the scene's tree: each node's path, UUID, material (own or inherited), the lights attached and the
    element it carries."""
    raise typer.Exit(_call("lumenlink.commands", "nodes", 22, scene=scene, server=server, create=create,
                           json_out=json_out) or 0)


@app.command()
def assign(
    scene: SceneOpt,
    path: Annotated[str, typer.Argument(help="The node's path (`lumenlink nodes` lists them) or UUID.")],
    material: Annotated[str | None, typer.Argument(
        help='Material JSON, e.g. \'{"type": "dielectric", "ior": 1.5}\'.')] = None,
    file: Annotated[Path | None, typer.Option(help="Read the material JSON from this file.")] = None,
    server: Server = "http://127.0.0.1:8000",
    create: Create = False,
) -> None:
    """Give a node a material (its descendants without one inherit it)."""
    raise typer.Exit(_call("lumenlink.commands", "assign", 22, scene=scene, path=path, material=material, file=file,
                           server=server, create=create) or 0)


@app.command("demo-guide")
def demo_guide(
    out_dir: Annotated[Path, typer.Option(help="Where the two maps go.")] = Path("demo-output"),
    photons: Annotated[int, typer.Option(help="Photons per pattern.")] = 400_000,
    pack: Annotated[bool, typer.Option(help="Also pack a uniform start to 0.95 min/max (before/after).")] = True,
) -> None:
    """An edge-lit light guide with its extraction dots as an optical element: uniform against graded dots, and a
    uniform start packed until its lit face is uniform."""
    raise typer.Exit(_call("lumenlink.guide_demo", "run", 36, out_dir=out_dir, photons=photons, pack=pack) or 0)


element_app = typer.Typer(help="Optical elements with an inside: --body/--file prepares one into the library (--id "
                                 "names one there), --node puts it onto a part, no option lists the library; "
                                 "`list`, `switch` and `remove` a scene's assignments.", add_completion=False)
app.add_typer(element_app, name="element")
Assignment = Annotated[str, typer.Argument(help="The element assignment: its id, or the node (path or UUID) that "
                                                "carries it.")]


@element_app.callback(invoke_without_command=True)
def element(
    ctx: typer.Context,
    body: Annotated[str | None, typer.Option(help="Element JSON (docs/DESIGN.md), e.g. a microstructure of domes on a "
                                                  "grid.")] = None,
    file: Annotated[Path | None, typer.Option(help="Read the element JSON from this file.")] = None,
    element_id: Annotated[str | None, typer.Option("--id", help="A library element's id (instead of a body).")] = None,
    scene: Annotated[str | None, typer.Option(help="Scene name or id (with --node).")] = None,
    node: Annotated[str | None, typer.Option(help="Put the element onto this node (path or UUID).")] = None,
    facing: Annotated[str | None, typer.Option(help="The node's faces that carry it: those facing X,Y,Z in its "
                                                    "frame.")] = None,
    faces: Annotated[str | None, typer.Option(help="The node's faces that carry it: its B-rep faces K[,K...] "
                                                   "(instead of --facing).")] = None,
    model: Annotated[str | None, typer.Option(help="exact (default: its micro-geometry traced) or bsdf (its "
                                                   "tabulated BSDF; a dielectric part, grid or hex layouts).")
                     ] = None,
    server: Server = "http://127.0.0.1:8000",
    create: Create = False,
) -> None:
    """Prepare an optical element with an inside into the library, put it onto a part, or list the library."""
    if ctx.invoked_subcommand is not None:
        return
    raise typer.Exit(_call("lumenlink.commands", "element", 36, scene=scene, server=server, body=body, file=file,
                           node=node, facing=facing, faces=faces, model=model, element_id=element_id,
                           create=create) or 0)


@element_app.command("list")
def element_list(
    scene: SceneOpt,
    server: Server = "http://127.0.0.1:8000",
    json_out: Annotated[bool, typer.Option("--json", help="Print the assignments as JSON.")] = False,
) -> None:
    """List the scene's element assignments: id, node, element, model, whether applied (and why not), support."""
    raise typer.Exit(_call("lumenlink.commands", "element_list", 54, scene=scene, server=server,
                           json_out=json_out) or 0)


@element_app.command("switch")
def element_switch(
    scene: SceneOpt,
    assignment: Assignment,
    element_id: Annotated[str, typer.Argument(help="The library element it carries from now on (a packed one, "
                                                   "say).")],
    server: Server = "http://127.0.0.1:8000",
) -> None:
    """Switch an assignment to another library element: the same node and faces."""
    raise typer.Exit(_call("lumenlink.commands", "element_switch", 54, scene=scene, server=server,
                           assignment=assignment, element_id=element_id) or 0)


@element_app.command("remove")
def element_remove(
    scene: SceneOpt,
    assignment: Assignment,
    server: Server = "http://127.0.0.1:8000",
) -> None:
    """Take an element off its part (the part's faces are plain again)."""
    raise typer.Exit(_call("lumenlink.commands", "element_remove", 54, scene=scene, server=server,
                           assignment=assignment) or 0)


@app.command("optical-file")
def optical_file(
    file: Annotated[Path | None, typer.Argument(help="A ray file (TM-25 or text columns) or a measured BRDF table; "
                                                     "none: list the uploaded files.")] = None,
    format: Annotated[str | None, typer.Option(  # noqa: A002 (the wire's name)
        help="tm25, rays or brdf (default: from the file's first bytes).")] = None,
    server: Server = "http://127.0.0.1:8000",
) -> None:
    """Upload a ray file or a measured BRDF table once; lights and materials then name it by the printed id."""
    raise typer.Exit(_call("lumenlink.commands", "optical_file", 38, server=server, file=file, format=format) or 0)


@app.command()
def pack(
    element_id: Annotated[str, typer.Argument(help="The density element to pack (its library id).")],
    scene: SceneOpt,
    assignment: Annotated[str, typer.Option(help="The element assignment that puts it onto the guide's face.")],
    sensor: Annotated[str, typer.Option(help="A grid sensor over the lit face (its cells are the meters).")],
    target: Annotated[float, typer.Option(help="The uniformity to reach, in (0, 1].")] = 0.8,
    figure: Annotated[str, typer.Option(help="min_max or min_mean.")] = "min_max",
    photons: Annotated[int, typer.Option(help="Photons of the first measurement (x4 as the map converges).")
                       ] = 100_000,
    max_photons: Annotated[int, typer.Option(help="The most photons of one measurement.")] = 1_600_000,
    max_iterations: Annotated[int, typer.Option(help="Budget: measurements at most.")] = 10,
    max_seconds: Annotated[float, typer.Option(help="Budget: seconds.")] = 600.0,
    damping: Annotated[float, typer.Option(help="The multiplicative step's exponent, in (0, 1] (smaller: slower, "
                                                "steadier).")] = 0.7,
    max_fill: Annotated[float, typer.Option(help="The largest fill a map cell may take, in (0, 1].")] = 1.0,
    pitch_mm: Annotated[float | None, typer.Option(help="The lattice pitch, mm (at least the feature's size; "
                                                        "default the element's).")] = None,
    seed: Annotated[int, typer.Option(help="Photon seed.")] = 1,
    switch: Annotated[bool, typer.Option("--switch", help="Put the packed element in place of the start.")] = False,
    png: Annotated[Path | None, typer.Option(help="Write pack.png here.")] = None,
    server: Server = "http://127.0.0.1:8000",
) -> None:
    """Pack a light guide's density element until its lit face is uniform (a job; Ctrl-C cancels it)."""
    raise typer.Exit(_call("lumenlink.commands", "pack", 41, element_id=element_id, scene=scene,
                           assignment=assignment, sensor=sensor, server=server, target=target, figure=figure,
                           photons=photons, max_photons=max_photons, max_iterations=max_iterations,
                           max_seconds=max_seconds, damping=damping, max_fill=max_fill, pitch_mm=pitch_mm,
                           seed=seed, switch=switch, png=png) or 0)


@app.command()
def light(
    scene: SceneOpt,
    ies: Annotated[Path | None, typer.Option(help="IES LM-63 (.ies) or EULUMDAT (.ldt) file.")] = None,
    at: Annotated[str | None, typer.Option(help="Where the light sits: X,Y,Z in metres (in the node's frame with "
                                                "--attach).")] = None,
    attach: Annotated[str | None, typer.Option(help="Node path or UUID the light moves with.")] = None,
    direction: Annotated[str | None, typer.Option(help="The file's gamma = 0 axis, X,Y,Z (default straight "
                                                       "down).")] = None,
    body: Annotated[str | None, typer.Option(help="Any light as a JSON body instead of --ies.")] = None,
    name: Annotated[str | None, typer.Option(help="A name for people.")] = None,
    server: Server = "http://127.0.0.1:8000",
    create: Create = False,
) -> None:
    """Add a light: a photometric file placed at a point, or a JSON body."""
    raise typer.Exit(_call("lumenlink.commands", "light", 22, scene=scene, server=server, ies=ies, at=at,
                           attach=attach, body=body, name=name, direction=direction, create=create) or 0)


@app.command()
def sensor(
    scene: SceneOpt,
    grid: Annotated[tuple[str, str, str, int, int] | None, typer.Option(
        metavar="ORIGIN U V NU NV", help="A grid sensor: the rectangle ORIGIN + s*U + t*V (each X,Y,Z in metres; "
                                         "front side U x V) in NU x NV cells, e.g. --grid -1,-1,0 2,0,0 0,2,0 20 "
                                         "20.")] = None,
    body: Annotated[str | None, typer.Option(help="Any sensor as a JSON body instead of --grid.")] = None,
    attach: Annotated[str | None, typer.Option(help="Node path or UUID the sensor moves with.")] = None,
    name: Annotated[str | None, typer.Option(help="A name for people (and for the files simulate writes).")] = None,
    server: Server = "http://127.0.0.1:8000",
    create: Create = False,
) -> None:
    """Add a sensor."""
    raise typer.Exit(_call("lumenlink.commands", "sensor", 22, scene=scene, server=server, grid=grid, body=body,
                           attach=attach, name=name, create=create) or 0)


@app.command()
def simulate(
    scene: SceneOpt,
    out: Annotated[Path, typer.Option(help="Directory for <sensor>.csv and <sensor>.png.")],
    sensor: Annotated[str, typer.Option(help="Sensor id or name, or `all`.")] = "all",
    target: Annotated[float | None, typer.Option(help="Stop at this relative error (0.01 = 1 %).")] = None,
    max_seconds: Annotated[float | None, typer.Option(help="Time budget per sensor, s.")] = None,
    max_photons: Annotated[int | None, typer.Option(help="Photon budget per sensor.")] = None,
    seed: Annotated[int, typer.Option(help="Same seed and revision: the same numbers.")] = 0,
    force_effects_off: Annotated[list[str] | None, typer.Option(
        "--force-effects-off", help="An effect the physics turned on to leave out (repeatable), e.g. "
                                    "`polarization`: faster, off by at most what its printed reason says.")] = None,
    tessellation_estimate: Annotated[bool, typer.Option(
        "--tessellation-estimate", help="Where the scene has curved mirror or glass meshes, also estimate their "
                                        "tessellation's error from refined meshes (3 to 4 times the time) and print "
                                        "it beside the bound.")] = False,
    server: Server = "http://127.0.0.1:8000",
) -> None:
    """Simulate sensors as jobs with a progress bar; write each one's CSV (cells, lux, stderr) and map; print why
    each effect the scene could call for is on or off, and the tessellation's error where there are curved optics."""
    raise typer.Exit(_call("lumenlink.commands", "simulate", 22, scene=scene, server=server, out=out,
                           sensor=sensor, target=target, max_seconds=max_seconds, max_photons=max_photons,
                           seed=seed, force_effects_off=force_effects_off or None,
                           **({"tessellation_estimate": True} if tessellation_estimate else {})) or 0)


@app.command()
def export(
    scene: SceneOpt,
    sensor: Annotated[str, typer.Option(help="The far-field sensor's id or name.")],
    out: Annotated[Path, typer.Option(help="The file to write.")],
    format: Annotated[str, typer.Option(help="`ies` (IES LM-63-2002) or `ldt` (EULUMDAT).")] = "ies",
    server: Server = "http://127.0.0.1:8000",
) -> None:
    """Write a far-field sensor's latest result (cd on a C-gamma grid) as an IES or EULUMDAT file."""
    raise typer.Exit(_call("lumenlink.commands", "export", 22, scene=scene, server=server, sensor=sensor,
                           format=format, out=out) or 0)


@app.command()
def compare(
    scene: SceneOpt,
    out: Annotated[Path, typer.Option(help="Directory for <sensor>_<from>_to_<to>.csv and .png.")],
    sensor: Annotated[str, typer.Option(help="Sensor id or name, or `all`.")] = "all",
    from_key: Annotated[str | None, typer.Option("--from", help="The earlier result: a scene revision R, or R.k (the "
                                                                "k-th state at R; an assignment keeps the "
                                                                "revision). Default: the second newest kept.")] = None,
    to_key: Annotated[str | None, typer.Option("--to", help="The later result (R or R.k). Default: the newest "
                                                            "kept.")] = None,
    server: Server = "http://127.0.0.1:8000",
) -> None:
    """Compare two kept results of each sensor: the change per cell (CSV) and its map (PNG)."""
    raise typer.Exit(_call("lumenlink.commands", "compare", 22, scene=scene, server=server, out=out, sensor=sensor,
                           from_key=from_key, to_key=to_key) or 0)


@app.command()
def ugr(
    scene: SceneOpt,
    sensor: Annotated[str, typer.Option(help="The camera (id or name): the observer at its position, looking along "
                                             "its line of sight.")],
    background: Annotated[float | None, typer.Option(help="Background luminance L_b, cd/m² (CIE 117: E_ind/π); "
                                                          "default: the image's non-source pixels.")] = None,
    threshold: Annotated[float | None, typer.Option(help="Pixels at least this bright (cd/m²) above the line of "
                                                         "sight are luminaires; default 5 × the image's mean.")] = None,
    simulate_first: Annotated[bool, typer.Option("--simulate/--latest", help="Simulate the camera first (default), "
                                                 "or rate its latest image.")] = True,
    max_seconds: Annotated[float | None, typer.Option(help="Time budget of the camera, s.")] = None,
    max_photons: Annotated[int | None, typer.Option(help="Path budget of the camera.")] = None,
    seed: Annotated[int, typer.Option(help="Same seed and revision: the same numbers.")] = 0,
    server: Server = "http://127.0.0.1:8000",
    json_out: Annotated[bool, typer.Option("--json", help="Print the answer as JSON.")] = False,
) -> None:
    """The unified glare rating (CIE 117) a camera's observer sees, with its error bar."""
    raise typer.Exit(_call("lumenlink.commands", "ugr", 37, scene=scene, server=server, sensor=sensor,
                           background=background, threshold=threshold, simulate_first=simulate_first,
                           max_seconds=max_seconds, max_photons=max_photons, seed=seed, json_out=json_out) or 0)


@app.command()
def uniformity(
    scene: SceneOpt,
    direction: Annotated[str, typer.Option(help="The way the meters look, X,Y,Z (e.g. 0,0,-1: down).")],
    nine_points: Annotated[tuple[str, str, str] | None, typer.Option(
        metavar="ORIGIN U V", help="The 9-point figure of the rectangle ORIGIN + s*U + t*V (each X,Y,Z, m).")] = None,
    point: Annotated[list[str] | None, typer.Option(help="A point a meter looks at, X,Y,Z (m); repeat it.")] = None,
    distance: Annotated[float | None, typer.Option(help="How far each meter stands back from its point, m "
                                                        "(default 0.5).")] = None,
    aperture: Annotated[float | None, typer.Option(help="Each meter's acceptance angle, degrees (default 1).")] = None,
    target: Annotated[float | None, typer.Option(help="Stop at this relative error (0.01 = 1 %).")] = None,
    max_seconds: Annotated[float | None, typer.Option(help="Time budget, s.")] = None,
    max_photons: Annotated[int | None, typer.Option(help="Path budget (all meters).")] = None,
    seed: Annotated[int, typer.Option(help="Same seed and revision: the same numbers.")] = 0,
    server: Server = "http://127.0.0.1:8000",
    json_out: Annotated[bool, typer.Option("--json", help="Print the answer as JSON.")] = False,
) -> None:
    """Luminance uniformity over a grid of meters: each reading (CSV on stdout) and min/max, min/mean ± error."""
    raise typer.Exit(_call("lumenlink.commands_luminance", "uniformity", 37, scene=scene, server=server,
                           direction=direction, nine_points=nine_points, points=point, distance=distance,
                           aperture=aperture, target=target, max_seconds=max_seconds, max_photons=max_photons,
                           seed=seed, json_out=json_out) or 0)


@app.command()
def conoscope(
    scene: SceneOpt,
    point: Annotated[str, typer.Option(help="The point of the lit face, X,Y,Z (m).")],
    normal: Annotated[str, typer.Option(help="The face's normal there, X,Y,Z (the viewing angles' axis).")],
    theta_max: Annotated[float | None, typer.Option(help="Largest polar angle, degrees (<= 85; default 80).")] = None,
    rings: Annotated[int | None, typer.Option(help="Polar angles from the normal to --theta-max.")] = None,
    azimuths: Annotated[int | None, typer.Option(help="Meters per ring.")] = None,
    distance: Annotated[float | None, typer.Option(help="How far each meter stands back, m.")] = None,
    aperture: Annotated[float | None, typer.Option(help="Each meter's acceptance angle, degrees.")] = None,
    target: Annotated[float | None, typer.Option(help="Stop at this relative error (0.01 = 1 %).")] = None,
    max_seconds: Annotated[float | None, typer.Option(help="Time budget, s.")] = None,
    max_photons: Annotated[int | None, typer.Option(help="Path budget (all meters).")] = None,
    seed: Annotated[int, typer.Option(help="Same seed and revision: the same numbers.")] = 0,
    png: Annotated[str | None, typer.Option(help="Also write the polar plot to this PNG file.")] = None,
    server: Server = "http://127.0.0.1:8000",
    json_out: Annotated[bool, typer.Option("--json", help="Print the answer as JSON.")] = False,
) -> None:
    """A conoscopic view: the luminance one point of a lit face shows against viewing angle (CSV on stdout)."""
    raise typer.Exit(_call("lumenlink.commands_luminance", "conoscope", 53, scene=scene, server=server, point=point,
                           normal=normal, theta_max=theta_max, rings=rings, azimuths=azimuths, distance=distance,
                           aperture=aperture, target=target, max_seconds=max_seconds, max_photons=max_photons,
                           seed=seed, png=png, json_out=json_out) or 0)


@app.command()
def demo(
    out_dir: Annotated[Path, typer.Option(help="Where the maps and the STEP files go.")] = Path("demo-output"),
    photons: Annotated[int, typer.Option(help="Photon budget per query.")] = 2_000_000,
    serve: Annotated[bool, typer.Option("--serve", help="Keep the service running afterwards (until Ctrl-C) and "
                                                        "print the address of the model's page.")] = False,
) -> None:
    """The main job end to end: CAD model, push, lights, illuminance, edit, push again."""
    code = _call("lumenlink.demo", "run", 7, out_dir=out_dir, photons=photons, serve=serve)
    raise typer.Exit(code or 0)


@app.command()
def bench(
    only: Annotated[list[str] | None, typer.Option(help="Run only these benchmarks (module names).")] = None,
    quick: Annotated[bool, typer.Option(help="Smaller cases, for a smoke run.")] = False,
) -> None:
    """Run the benchmarks; results go to bench/results/*.json and bench/results/REPORT.md."""
    code = _call("bench.run", "main", 2, only=only or [], quick=quick)
    raise typer.Exit(code or 0)


if __name__ == "__main__":
    app()
