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
) -> None:
    """Start the REST service (uvicorn)."""
    _call("service.server", "run", 5, host=host, port=port, data_dir=data_dir, warm=warm, token=token, dask=dask)


@app.command()
def push(
    file: Annotated[Path, typer.Argument(help="STEP file to read.", exists=False)],
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
    file: Annotated[Path, typer.Argument(help="STEP file to watch.")],
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


@app.command()
def demo(
    out_dir: Annotated[Path, typer.Option(help="Where the maps and the STEP files go.")] = Path("demo-output"),
    photons: Annotated[int, typer.Option(help="Photon budget per query.")] = 2_000_000,
) -> None:
    """The main job end to end: CAD model, push, lights, illuminance, edit, push again."""
    code = _call("lumenlink.demo", "run", 7, out_dir=out_dir, photons=photons)
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
