"""``lumenlink push`` and ``lumenlink watch``: read, identify, tessellate, upload what is missing, push.

Exit codes: 0 pushed; 2 the document cannot be read (missing, not STEP, empty) or bad options;
3 the service cannot be reached; 4 the scene changed meanwhile (409, nothing pushed); 1 any other
failure of the push. Progress bars and messages go to stderr, the summary (or ``--json``: the service's
answer) to stdout.
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from .errors import CadAdapterError, CadImportError, PushError, RevisionConflict, ServiceUnavailable, TessellationError
from .tessellate import Settings, TessellationCache

EXIT_OK, EXIT_FAILED, EXIT_INPUT, EXIT_UNREACHABLE, EXIT_CONFLICT = 0, 1, 2, 3, 4


def default_cache_dir() -> Path:
    """``$LUMENLINK_CACHE_DIR``, else ``$XDG_CACHE_HOME/lumenlink/meshes``, else ``~/.cache/lumenlink/meshes``."""
    if os.environ.get("LUMENLINK_CACHE_DIR"):
        return Path(os.environ["LUMENLINK_CACHE_DIR"])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "lumenlink" / "meshes"


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
        f"  diff: {diff}, unchanged {a.get('unchanged', '?')}",
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


def push_once(file: Path, scene: str, server: str, linear: float | None, angular: float | None, relative: bool,
              cache: TessellationCache, console: Console, json_out: bool = False,
              transport: Any = None) -> int:
    """Read, identify, tessellate and push one file; report on ``console`` (stderr) and stdout."""
    from . import read_document
    from .client import Pusher
    from .tessellate import tessellate

    try:
        t0 = time.perf_counter()
        with console.status(f"reading {file.name}", spinner="dots") if console.is_terminal else _null():
            doc = read_document(file)
        read_seconds = time.perf_counter() - t0
        for w in doc.warnings:
            console.print(f"[yellow]warning:[/] {w}")
        counts: dict[str, int] = {}
        for n in doc.nodes:
            counts[n.match or "?"] = counts.get(n.match or "?", 0) + 1
        console.print(f"{file.name}: {len(doc.nodes)} nodes, {len(doc.parts)} distinct parts, unit {doc.length_unit}; "
                      "UUIDs " + ", ".join(f"{k} {v}" for k, v in counts.items()))
        settings = Settings.default(doc.length_unit, linear, angular, relative)
        with _progress(console) as bar:
            task = bar.add_task("tessellating", total=len(doc.parts))
            tess = tessellate(doc, settings, cache=cache,
                              progress=lambda done, total, name: bar.update(task, completed=done))
        for w in tess.warnings:
            console.print(f"[yellow]warning:[/] {w}")
        for key, why in tess.failed.items():
            nodes = [n.path for n in doc.nodes if n.part == key]
            console.print(f"[red]tessellation failed[/] for part {doc.parts[key].name!r} ({why}); pushed without "
                          f"geometry: {', '.join(nodes[:5])}{' ...' if len(nodes) > 5 else ''}")
    except (CadImportError, TessellationError) as exc:
        console.print(f"[red]error:[/] {exc}")
        return EXIT_INPUT
    except CadAdapterError as exc:
        console.print(f"[red]error:[/] {exc}")
        return EXIT_FAILED
    try:
        with _progress(console) as bar:
            task = bar.add_task("uploading meshes", total=None)

            def up(done: int, total: int, gid: str) -> None:
                bar.update(task, completed=done, total=total)

            with Pusher(server, transport=transport, upload_progress=up) as pusher:
                result = pusher.push(doc, tess, scene)
    except RevisionConflict as exc:
        console.print(f"[red]conflict:[/] {exc}")
        return EXIT_CONFLICT
    except ServiceUnavailable as exc:
        console.print(f"[red]error:[/] {exc}")
        return EXIT_UNREACHABLE
    except (PushError, CadAdapterError) as exc:
        console.print(f"[red]error:[/] {exc}")
        return EXIT_FAILED
    if json_out:
        sys.stdout.write(json.dumps(result.answer, indent=2) + "\n")
    else:
        sys.stdout.write(summary(result, doc, tess, read_seconds) + "\n")
    sys.stdout.flush()
    return EXIT_OK


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


def push(file: Path, scene: str, server: str, linear: float | None = None, angular: float | None = None,
         relative: bool = False, json_out: bool = False, *, transport: Any = None,
         cache_dir: Path | None = None) -> int:
    """``lumenlink push FILE --scene NAME``: one push; returns the exit code."""
    console = Console(stderr=True, soft_wrap=True)
    if not _check_options(linear, angular, relative, console):
        return EXIT_INPUT
    cache = TessellationCache(cache_dir if cache_dir is not None else default_cache_dir())
    return push_once(Path(file), scene, server, linear, angular, relative, cache, console, json_out, transport)


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
    if not _check_options(linear, angular, relative, console):
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
                    pushed_stamp = stamp
                    pushes += 1
                    if max_pushes is not None and pushes >= max_pushes:
                        return last_code
            if timeout is not None and now - start > timeout:
                return last_code
            time.sleep(poll)
    except KeyboardInterrupt:
        console.print("watch stopped")
        return EXIT_OK
