"""``lumenlink simulate | export | compare``: answers from the command line, each sensor's CSV and picture and
what changed between two kept results; built on `lumenlink.Client`, exit codes as `lumenlink.commands`."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

from lumenlink.client import Client, LumenLinkError
from lumenlink.commands import (
    EXIT_OK,
    _pm,
    _progress_update,
    _reasons,
    _run,
    _warn,
)
from lumenlink.options import DEFAULT_SERVER, SceneOpt, Seed, Server
from lumenlink.sensor_outputs import output_of


def _file_stem(sensor: dict[str, Any], taken: set[str]) -> str:
    """The sensor's name made safe for a file name, else its id; unique within one run."""
    name = re.sub(r"[^A-Za-z0-9._-]+", "_", str(sensor["body"].get("name") or "")).strip("._")
    stem = name or sensor["id"]
    if stem in taken:
        stem = f"{stem}-{sensor['id'][:8]}"
    taken.add(stem)
    return stem


def _flat(x: Any) -> list[Any]:
    return [z for y in x for z in _flat(y)] if isinstance(x, list) else [x]


def _tessellation(result: dict[str, Any]) -> None:
    """The answer's tessellation error, where it has one: the bound and, where asked, the estimate with its cost
    (largest over the values, and at the brightest value), lx."""
    budget = result.get("error_budget") or {}
    if not budget.get("tessellation"):
        return
    lux = [float(x) for x in _flat(result.get("lux") or [])]
    bound = [float(x) for x in _flat(budget["tessellation"])]
    k = max(range(len(lux)), key=lambda i: lux[i]) if lux else 0
    line = f"  tessellation: bound <= {max(bound):.4g} lx"
    if budget.get("tessellation_estimate") is not None:
        est = [float(x) for x in _flat(budget["tessellation_estimate"])]
        se = [float(x) for x in _flat(budget["tessellation_estimate_stderr"])]
        j = max(range(len(est)), key=lambda i: est[i])
        line += (f"; estimate {est[j]:.4g} +- {se[j]:.2g} lx at most, {est[k]:.4g} lx at the brightest value "
                 f"({lux[k]:.4g} lx) [{budget.get('tessellation_estimate_levels')} refinements, "
                 f"{float(budget.get('tessellation_estimate_seconds') or 0):.2f} s]")
    else:
        line += " (a bound; --tessellation-estimate estimates the error itself)"
    print(line)


def _uniformity(result: dict[str, Any]) -> None:
    """A grid's or points' uniformity: min/max and min/mean of its values ± their standard errors (delta method,
    `tracer.photometry.glare.uniformity`); nothing for one value, a surface (min over triangles of very different
    sizes: see its robust max) or a result without values."""
    if not output_of(result).UNIFORMITY:
        return
    lux = [float(x) for x in _flat(result.get("lux") or [])]
    if len(lux) < 2:
        return
    if not max(lux) > 0:
        print(f"  uniformity over {len(lux)} values: undefined (every value is 0 lx)")
        return
    from tracer.photometry.glare import uniformity

    u = uniformity(lux, [float(x) for x in _flat(result["stderr"])])
    print(f"  uniformity over {len(lux)} values: min/max {_pm(u['min_max'], u['min_max_stderr'])}, min/mean "
          f"{_pm(u['min_mean'], u['min_mean_stderr'])}")


def _out_dir(out: Path) -> Path:
    """`--out` as a folder (made later, where it is missing); a usage error where it is a file."""
    out_dir = Path(out)
    if out_dir.exists() and not out_dir.is_dir():
        raise LumenLinkError(f"--out {out_dir} is a file, not a directory", usage=True)
    return out_dir

def simulate(
    scene: SceneOpt,
    out: Annotated[Path, typer.Option(help="Directory for <sensor>.csv and <sensor>.png.")],
    sensor: Annotated[str, typer.Option(help="Sensor id or name, or `all`.")] = "all",
    target: Annotated[float | None, typer.Option(help="Stop at this relative error (0.01 = 1 %).")] = None,
    max_seconds: Annotated[float | None, typer.Option(help="Time budget per sensor, s.")] = None,
    max_photons: Annotated[int | None, typer.Option(help="Photon budget per sensor.")] = None,
    seed: Seed = 0,
    force_effects_off: Annotated[list[str] | None, typer.Option(
        "--force-effects-off", help="An effect the physics turned on to leave out (repeatable), e.g. "
                                    "`polarization`: faster, off by at most what its printed reason says.")] = None,
    tessellation_estimate: Annotated[bool, typer.Option(
        "--tessellation-estimate", help="Where the scene has curved mirror or glass meshes, also estimate their "
                                        "tessellation's error from refined meshes (3 to 4 times the time) and print "
                                        "it beside the bound.")] = False,
    server: Server = DEFAULT_SERVER,
) -> int:
    """Simulate sensors as jobs with a progress bar; write each one's CSV (cells, lux, stderr) and map; print why
    each effect the scene could call for is on or off, and the tessellation's error where there are curved optics."""
    def work(console: Console) -> int:
        out_dir = _out_dir(out)
        with Client(server) as ll:
            info = ll.scene(scene)
            listed = {s["id"]: s for s in ll.sensors(info)}
            chosen = ll._sensor_ids(info["id"], sensor)
            out_dir.mkdir(parents=True, exist_ok=True)
            taken: set[str] = set()
            progress = Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.fields[state]}"),
                                TimeElapsedColumn(), console=console, transient=True,
                                disable=not console.is_terminal)
            for s in chosen:
                stem = _file_stem(listed.get(s["id"], s), taken)
                with progress:
                    task = progress.add_task(f"sensor {stem}", total=None, state="queued")
                    update = _progress_update(progress, task, target, max_seconds, max_photons)
                    result = ll.simulate(info, s["id"], target=target, max_seconds=max_seconds,
                                         max_photons=max_photons, seed=seed, progress=update,
                                         force_effects_off=force_effects_off or None,
                                         tessellation_estimate=tessellation_estimate)[s["id"]]
                _write_result(ll, info, s, stem, result, out_dir, console)
        return EXIT_OK
    return _run(work)


def _write_result(ll: Client, info: dict[str, Any], s: dict[str, Any], stem: str, result: dict[str, Any],
                  out_dir: Path, console: Console) -> None:
    """One sensor's answer from `simulate`: its CSV and the files its kind writes beside it (a map, images, an IES
    file: `lumenlink.sensor_outputs`), its summary line, why each effect is on or off, and for illuminance its
    uniformity and the tessellation's error where it has them."""
    kind = output_of(result)
    csv_path = out_dir / f"{stem}.csv"
    csv_path.write_text(kind.csv(result), encoding="utf-8")
    written = [csv_path, *kind.files(ll, info, s["id"], stem, out_dir,
                                     lambda text: console.print(f"[yellow]warning:[/] {escape(text)}"))]
    _warn(console, result)
    _reasons(result)
    print(f"sensor {stem} ({s['id']}): {kind.summary(result)} -> " + ", ".join(str(p) for p in written))
    if kind.LUX:
        _uniformity(result)
        _tessellation(result)


def export(
    scene: SceneOpt,
    sensor: Annotated[str, typer.Option(help="The far-field sensor's id or name.")],
    out: Annotated[Path, typer.Option(help="The file to write.")],
    format: Annotated[str, typer.Option(help="`ies` (IES LM-63-2002) or `ldt` (EULUMDAT).")] = "ies",
    server: Server = DEFAULT_SERVER,
) -> int:
    """Write a far-field sensor's latest result (cd on a C-gamma grid) as an IES or EULUMDAT file."""
    def work(console: Console) -> int:
        if format not in ("ies", "ldt"):
            raise LumenLinkError(f"--format is ies (IES LM-63) or ldt (EULUMDAT), got {format!r}", usage=True)
        if Path(out).is_dir():
            raise LumenLinkError(f"--out {out} is a directory: give the file to write, e.g. {Path(out) / 'lamp'}."
                                 f"{format}", usage=True)
        with Client(server) as ll:
            info = ll.scene(scene)
            text = ll.export(info, sensor, format, out=out)
        lines = text.count("\n")
        print(f"sensor {sensor}: {'IES LM-63-2002' if format == 'ies' else 'EULUMDAT'} ({lines} lines) -> {out}")
        return EXIT_OK
    return _run(work)


def compare(
    scene: SceneOpt,
    out: Annotated[Path, typer.Option(help="Directory for <sensor>_<from>_to_<to>.csv and .png.")],
    sensor: Annotated[str, typer.Option(help="Sensor id or name, or `all`.")] = "all",
    from_key: Annotated[str | None, typer.Option("--from", help="The earlier result: a scene revision R, or R.k (the "
                                                                "k-th state at R; an assignment keeps the "
                                                                "revision). Default: the second newest kept.")] = None,
    to_key: Annotated[str | None, typer.Option("--to", help="The later result (R or R.k). Default: the newest "
                                                            "kept.")] = None,
    server: Server = DEFAULT_SERVER,
) -> int:
    """Compare two kept results of each sensor: the change per cell (CSV) and its map (PNG)."""
    def work(console: Console) -> int:
        out_dir = _out_dir(out)
        with Client(server) as ll:
            info = ll.scene(scene)
            names = {s["id"]: s["body"].get("name") or s["id"] for s in ll.sensors(info)}
            answers = ll.compare(info, sensor, from_key, to_key, out=out_dir)
        for sensor_id, d in answers.items():
            s = d["summary"]
            unit = "cd/m2" if d.get("quantity") == "luminance" else "lx"
            before, after = (s.get(f"mean_{w}_lux", s.get(f"mean_{w}_cd_m2")) for w in ("before", "after"))
            line = (f"sensor {names.get(sensor_id, sensor_id)} ({sensor_id}): {d['from']} -> {d['to']}: mean "
                    f"{before:.4g} -> {after:.4g} {unit}; {s['significant']}/{s['cells']} "
                    f"cells changed beyond {d['significance_sigmas']:g} sigma ({s['increased']} brighter, "
                    f"{s['decreased']} darker)")
            if s.get("max_increase_lux"):
                line += f"; largest rise +{s['max_increase_lux']:.4g} lx at ({_xyz(s['max_increase_at'])}) m"
            if s.get("max_decrease_lux"):
                line += f"; largest fall -{s['max_decrease_lux']:.4g} lx at ({_xyz(s['max_decrease_at'])}) m"
            print(line + " -> " + ", ".join(d["files"]))
            for w in d.get("warnings") or []:
                console.print(f"[yellow]warning:[/] {escape(w)}")
        return EXIT_OK
    return _run(work)


def _xyz(p: list[float]) -> str:
    return ", ".join(f"{c:.3g}" for c in p)
