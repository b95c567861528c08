"""``lumenlink push`` and ``lumenlink watch``: read, identify, tessellate, upload what is missing, push.

Exit codes: 0 pushed; 2 the document cannot be read (missing, not STEP, empty) or bad options;
3 the service cannot be reached; 4 the scene changed meanwhile (409, nothing pushed); 1 any other
failure of the push. Progress bars and messages go to stderr, the summary (or ``--json``: the service's
answer) to stdout.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from .errors import CadAdapterError, CadImportError, PushError, RevisionConflict, ServiceUnavailable, TessellationError
from .freecad import is_freecad_file
from .push import default_cache_dir, push_file
from .tessellate import Settings, TessellationCache

EXIT_OK, EXIT_FAILED, EXIT_INPUT, EXIT_UNREACHABLE, EXIT_CONFLICT = 0, 1, 2, 3, 4


def _progress(console: Console) -> Progress:
    return Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                    console=console, transient=True, disable=not console.is_terminal)


def summary(result: Any, doc: Any, tess: Any, read_seconds: float) -> str:
    """One human-readable paragraph: the diff, rebuilds, uploads and the seconds of every stage."""
    a = result.answer
    lists = ("added", "removed", "moved", "geometry_changed", "renamed", "reparented", "recolored")
    diff = ", ".join(f"{k.replace('_', ' ')} {len(a.get(k) or [])}" for k in lists if k in a)
    lines = [
        f"scene {a.get('scene', result.scene_id)}: revision {a.get('base_revision')} -> {a.get('revision')}"
        + (" (scene created)" if result.created_scene else ""),
        f"  diff: {diff}, unchanged {a.get('unchanged', '?')}"
        + (f"; restored {len(a['restored_nodes'])} removed node(s) under their old UUIDs" if a.get("restored_nodes")
           else ""),
        f"  bottom levels: built {a.get('blas_built', '?')}, reused {a.get('blas_reused', '?')}, "
        f"loaded {a.get('blas_loaded', '?')}; instances {a.get('instances', '?')}",
        f"  meshes: {result.geometries} distinct, {result.uploaded} uploaded ({result.uploaded_bytes / 1e3:.1f} kB); "
        f"tessellated {tess.meshed}, from cache {tess.cached}, {tess.triangles} triangles",
        f"  seconds: read {read_seconds:.2f}, tessellate {tess.seconds:.2f}, "
        + ", ".join(f"{k} {v:.2f}" for k, v in result.seconds.items())
        + ("; service " + ", ".join(f"{k} {float(v):.3f}" for k, v in (a.get("seconds") or {}).items())
           if a.get("seconds") else ""),
    ]
    return "\n".join(lines)


def identity_report(doc: Any) -> list[str]:
    """Lines saying how the UUIDs were found: from where, nodes per rule, and every ambiguous node."""
    rec = doc.reconciliation or {}
    counts = ", ".join(f"{k} {v}" for k, v in (rec.get("matched") or {}).items() if v)
    lines = [f"identity (memory: {rec.get('source', 'none')}): {counts}"]
    detail = doc.reconciliation_detail or {}
    if detail.get("snapped") or detail.get("reused_geometries"):
        lines.append(f"  within tolerance: {detail.get('snapped', 0)} placement(s) kept, "
                     f"{detail.get('reused_geometries', 0)} geometry id(s) kept (not meshed, not uploaded)")
    for name, h in (detail.get("same_surface") or {}).items():
        lines.append(f"  {name}: B-rep edited by the writer, surfaces {h:.3g} apart (Hausdorff)")
    for a in rec.get("ambiguous") or []:
        lines.append(f"  [yellow]ambiguous:[/] {a['path']}: {a['reason']}")
    return lines


def orphan_report(answer: dict, previous: list[dict] | None) -> list[str]:
    """Loud lines for assignments a push orphaned (or, in a dry run, would orphan), with node paths."""
    paths = {r.get("uuid"): r.get("path") or r.get("name") for r in previous or []}
    out = []
    for o in answer.get("orphaned") or []:
        where = paths.get(o.get("node")) or o.get("node")
        out.append(f"[bold red]ORPHANED[/] {o.get('kind')} {o.get('id')} on removed node {where!r} "
                   f"({o.get('node')}); it comes back if that node does, `DELETE /scenes/{{id}}/orphans` purges it")
    return out


def push_once(file: Path, scene: str, server: str, linear: float | None, angular: float | None, relative: bool,
              cache: TessellationCache, console: Console, json_out: bool = False,
              transport: Any = None, dry_run: bool = False) -> int:
    """`push_file`, reported on ``console`` (stderr) and stdout; returns the exit code."""

    def on_read(doc: Any) -> None:
        for w in doc.warnings:
            console.print(f"[yellow]warning:[/] {w}")
        console.print(f"{file.name}: {len(doc.nodes)} nodes, {len(doc.parts)} distinct parts, unit {doc.length_unit}")
        for line in identity_report(doc):
            console.print(line)
        bar.start()
        bar.update(task, total=len(doc.parts))

    bar = _progress(console)
    task = bar.add_task("tessellating / uploading", total=None)
    try:
        try:
            result, doc, tess, read_seconds, previous = push_file(
                file, scene, server, linear, angular, relative, cache=cache, transport=transport, dry_run=dry_run,
                on_read=on_read, tessellation_progress=lambda done, total, name: bar.update(task, completed=done),
                upload_progress=lambda done, total, gid: bar.update(task, description="uploading meshes",
                                                                    completed=done, total=total))
        finally:
            bar.stop()
    except (CadImportError, TessellationError) as exc:
        console.print(f"[red]error:[/] {exc}")
        return EXIT_INPUT
    except PushError as exc:  # ServiceUnavailable and RevisionConflict included
        return _service_failure(exc, console)
    except CadAdapterError as exc:
        console.print(f"[red]error:[/] {exc}")
        return EXIT_FAILED
    for w in tess.warnings:
        console.print(f"[yellow]warning:[/] {w}")
    for key, why in tess.failed.items():
        nodes = [n.path for n in doc.nodes if n.part == key]
        console.print(f"[red]tessellation failed[/] for part {doc.parts[key].name!r} ({why}); pushed without "
                      f"geometry: {', '.join(nodes[:5])}{' ...' if len(nodes) > 5 else ''}")
    for line in orphan_report(result.answer, previous):
        console.print(line)
    if json_out:
        sys.stdout.write(json.dumps(result.answer, indent=2) + "\n")
    elif dry_run:
        sys.stdout.write(dry_run_summary(result.answer) + "\n")
    else:
        sys.stdout.write(summary(result, doc, tess, read_seconds) + "\n")
    sys.stdout.flush()
    return EXIT_OK


def _service_failure(exc: CadAdapterError, console: Console) -> int:
    """Report a failed exchange with the service; the exit code that says which kind."""
    if isinstance(exc, RevisionConflict):
        console.print(f"[red]conflict:[/] {exc}")
        return EXIT_CONFLICT
    console.print(f"[red]error:[/] {exc}")
    return EXIT_UNREACHABLE if isinstance(exc, ServiceUnavailable) else EXIT_FAILED


def dry_run_summary(a: dict) -> str:
    """What a push would do: the diff, the bottom levels to build and meshes to upload; nothing was changed."""
    lists = ("added", "removed", "moved", "geometry_changed", "renamed", "reparented", "recolored")
    diff = ", ".join(f"{k.replace('_', ' ')} {len(a.get(k) or [])}" for k in lists if k in a)
    return "\n".join([
        f"dry run (nothing changed): scene {a.get('scene') or '(would be created)'} at revision {a.get('revision')}",
        f"  diff: {diff}, unchanged {a.get('unchanged', '?')}"
        + (f"; would restore {len(a['restored_nodes'])} removed node(s) under their old UUIDs"
           if a.get("restored_nodes") else ""),
        f"  would build {len(a.get('blas_to_build') or [])} bottom level(s), upload "
        f"{len(a.get('missing_geometries') or [])} mesh(es); would orphan {len(a.get('orphaned') or [])} "
        f"assignment(s), restore {len(a.get('restored') or [])}",
    ])


class _null:
    def __enter__(self) -> None:
        return None

    def __exit__(self, *exc: object) -> None:
        return None


def _check_options(linear: float | None, angular: float | None, relative: bool, console: Console) -> bool:
    try:
        Settings.default("mm", linear, angular, relative)
    except TessellationError as exc:
        console.print(f"[red]error:[/] {exc}")
        return False
    return True


def _check_server(server: str, console: Console) -> bool:
    """A URL without a scheme is bad usage (exit 2), said with what to add (the client's own check)."""
    from lumenlink.http import check_server  # loads httpx: only when a command talks to a service

    try:
        check_server(server, PushError)
    except PushError as exc:
        console.print(f"[red]error:[/] {exc}")
        return False
    return True


def push(file: Path, scene: str, server: str, linear: float | None = None, angular: float | None = None,
         relative: bool = False, json_out: bool = False, *, transport: Any = None,
         cache_dir: Path | None = None, dry_run: bool = False) -> int:
    """``lumenlink push FILE --scene NAME``: one push; returns the exit code."""
    console = Console(stderr=True, soft_wrap=True)
    if not _check_options(linear, angular, relative, console) or not _check_server(server, console):
        return EXIT_INPUT
    cache = TessellationCache(cache_dir if cache_dir is not None else default_cache_dir())
    return push_once(Path(file), scene, server, linear, angular, relative, cache, console, json_out, transport,
                     dry_run=dry_run)


def _stamp(path: Path) -> tuple[int, int] | None:
    try:
        st = path.stat()
    except OSError:
        return None
    return (st.st_mtime_ns, st.st_size)


def watch(file: Path, scene: str, server: str, linear: float | None = None, angular: float | None = None,
          relative: bool = False, debounce: float = 0.5, *, poll: float = 0.2, max_pushes: int | None = None,
          timeout: float | None = None, transport: Any = None, cache_dir: Path | None = None) -> int:
    """``lumenlink watch FILE``: push now, then again whenever the file changes and stays unchanged for
    ``debounce`` seconds (a CAD program writes a file in several steps). Stops on Ctrl-C.

    ``max_pushes`` and ``timeout`` (seconds) stop the loop early, for tests and scripts. A push that fails
    (a half-written file, the service down, a 409) is reported and the watch goes on; the tessellation
    cache stays in memory, so each push meshes only the parts that changed.
    """
    console = Console(stderr=True, soft_wrap=True)
    if not _check_options(linear, angular, relative, console) or not _check_server(server, console):
        return EXIT_INPUT
    if not isinstance(debounce, int | float) or debounce < 0:
        console.print(f"[red]error:[/] debounce must be a number of seconds >= 0, got {debounce!r}")
        return EXIT_INPUT
    file = Path(file)
    if not file.exists():
        console.print(f"[red]error:[/] {file}: no such file")
        return EXIT_INPUT
    cache = TessellationCache(cache_dir if cache_dir is not None else default_cache_dir())
    start = time.monotonic()
    pushes = 0
    last_code = EXIT_OK
    pushed_stamp = None
    pending_since: float | None = None
    pending_stamp = None
    try:
        while True:
            stamp = _stamp(file)
            now = time.monotonic()
            if stamp is not None and stamp != pushed_stamp:
                if stamp != pending_stamp:
                    pending_stamp, pending_since = stamp, now
                elif pending_since is not None and now - pending_since >= debounce:
                    console.print(f"[bold]{time.strftime('%H:%M:%S')}[/] {file.name} changed: pushing")
                    last_code = push_once(file, scene, server, linear, angular, relative, cache, console,
                                          transport=transport)
                    # a FreeCAD document's push writes the UUIDs it issued into the file: that is not a change
                    pushed_stamp = _stamp(file) if is_freecad_file(file) else stamp
                    pushes += 1
                    if max_pushes is not None and pushes >= max_pushes:
                        return last_code
            if timeout is not None and now - start > timeout:
                return last_code
            time.sleep(poll)
    except KeyboardInterrupt:
        console.print("watch stopped")
        return EXIT_OK
