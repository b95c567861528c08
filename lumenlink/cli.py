"""The `lumenlink` command: one subcommand per job. The engineer's loop (`lumenlink.commands` and its siblings,
built on `lumenlink.Client`) is registered as declared there; the service, the CAD adapter, the demos and the
benchmarks are imported only when their command runs: importing the CAD stack or numba costs seconds, so
`lumenlink --help` imports neither.
"""

from __future__ import annotations

import functools
import importlib
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import typer

from lumenlink import commands, commands_elements, commands_luminance, commands_results

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


# ---------------------------------------------------------------- the engineer's loop (issue 22)
# Each command declares its options once, in its own signature beside its code (built on lumenlink.Client); exit
# codes as push: 2 bad usage (options, files, a URL without its scheme, an unknown scene or node path, a body the
# service refuses), 3 the service unreachable, 1 anything else.


def exits(command: Callable[..., int | None]) -> Callable[..., None]:
    """`command` as typer runs it: its options are its own signature's (`functools.wraps` hands typer the signature
    and the docstring), its return value the exit code (a callback that returns 0 lets its subcommand run)."""
    @functools.wraps(command)
    def run(*args: Any, **kwargs: Any) -> None:
        code = command(*args, **kwargs)
        if code:
            raise typer.Exit(code)
    return run


for _command in (commands.nodes, commands.assign, commands.light, commands.sensor, commands_results.simulate,
                 commands_results.export, commands_results.compare):
    app.command()(exits(_command))
element_app = typer.Typer(help="Optical elements with an inside: --body/--file prepares one into the library (--id "
                                 "names one there), --node puts it onto a part, no option lists the library; "
                                 "`list`, `switch` and `remove` a scene's assignments.", add_completion=False)
app.add_typer(element_app, name="element")
element_app.callback(invoke_without_command=True)(exits(commands_elements.element))
for _name, _command in (("list", commands_elements.element_list), ("switch", commands_elements.element_switch),
                        ("remove", commands_elements.element_remove)):
    element_app.command(_name)(exits(_command))
for _command in (commands_elements.optical_file, commands_elements.pack, commands_elements.design,
                 commands_luminance.ugr, commands_luminance.uniformity, commands_luminance.conoscope):
    app.command()(exits(_command))


@app.command("demo-guide")
def demo_guide(
    out_dir: Annotated[Path, typer.Option(help="Where the two maps go.")] = Path("demo-output"),
    photons: Annotated[int, typer.Option(help="Photons per pattern.")] = 400_000,
    pack: Annotated[bool, typer.Option(help="Also pack a uniform start to 0.95 min/max (before/after).")] = True,
) -> None:
    """An edge-lit light guide with its extraction dots as an optical element: uniform against graded dots, and a
    uniform start packed until its lit face is uniform."""
    raise typer.Exit(_call("lumenlink.guide_demo", "run", 36, out_dir=out_dir, photons=photons, pack=pack) or 0)


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


def _unloadable(where: str, exc: Exception) -> Callable[[], None]:
    def command() -> None:
        typer.echo(f"lumenlink: {where} cannot be loaded: {exc}", err=True)
        raise typer.Exit(2)
    return command


def add_installed_commands() -> None:
    """The commands installed packages add to `lumenlink` (entry points of group ``lumenlink.commands``: the CAD
    adapter's push, watch and freecad-addon, `cad_adapter.commands`), so that this command line names no package
    built on it. One that cannot be loaded is still listed and says why when run (exit 2)."""
    from importlib.metadata import entry_points

    for ep in sorted(entry_points(group="lumenlink.commands"), key=lambda e: e.name):
        try:
            command = ep.load()
        except Exception as exc:   # noqa: BLE001 - a broken plugin must not take the other commands down
            command = _unloadable(ep.value, exc)
        app.command(ep.name)(command)


add_installed_commands()

if __name__ == "__main__":
    app()
