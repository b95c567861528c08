"""Push a STEP file to a scene: read it, recognise its nodes in what the scene holds, tessellate what changed and
upload it. The library under ``lumenlink push`` and ``watch`` (`cad_adapter.commands`, added to the command line as
plugins, and `cad_adapter.cli`, which prints) and `lumenlink.Client.push`: `lumenlink` imports this module, never the
adapter's command line."""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Any

from .tessellate import Settings, TessellationCache


def default_cache_dir() -> Path:
    """``$LUMENLINK_CACHE_DIR``, else ``$XDG_CACHE_HOME/lumenlink/meshes``, else ``~/.cache/lumenlink/meshes``."""
    if os.environ.get("LUMENLINK_CACHE_DIR"):
        return Path(os.environ["LUMENLINK_CACHE_DIR"])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "lumenlink" / "meshes"


def push_file(file: Path, scene: str, server: str, linear: float | None = None, angular: float | None = None,
              relative: bool = False, *, cache: TessellationCache | None = None, transport: Any = None,
              dry_run: bool = False, on_read: Any = None, tessellation_progress: Any = None,
              upload_progress: Any = None, token: str | None = None) -> tuple[Any, Any, Any, float, list[dict] | None]:
    """Read a STEP file, recognise its nodes in the scene called `scene` (`identify` against what the scene holds),
    tessellate what changed and push it: what ``lumenlink push`` does, without printing (`lumenlink.Client.push`
    calls it too). A FreeCAD document (.FCStd) carries its own UUIDs: `cad_adapter.freecad.push_fcstd`.
    ``on_read(doc)`` is called once the file is read and identified; the progress callables as `tessellate`'s and
    `Pusher`'s. Returns (PushResult, Document, Tessellation, read seconds, the scene's nodes before the push or
    None). Raises the adapter's errors (`CadImportError`, `TessellationError`, `PushError`...). ``dry_run``: diff
    only; no upload, no sidecar, no scene. ``token``: the bearer token (None: ``$LUMENLINK_TOKEN``)."""
    from .freecad import is_freecad_file, push_fcstd

    if is_freecad_file(file):
        return push_fcstd(file, scene, server, linear, angular, relative, transport=transport, dry_run=dry_run,
                          on_read=on_read, upload_progress=upload_progress, token=token)
    from .client import Pusher
    from .identity import confirm_same_surface, identify
    from .step_reader import read_step
    from .tessellate import tessellate

    with Pusher(server, transport=transport, token=token) as pusher:
        tree = pusher.scene_tree(scene)
    previous = tree.nodes if tree is not None else None
    t0 = time.perf_counter()
    doc = read_step(file)
    settings = Settings.default(doc.length_unit, linear, angular, relative)
    same_settings = tree is not None and tree.tessellation is not None and all(
        tree.tessellation.get(k) == v for k, v in settings.as_dict().items())
    identify(doc, write=not dry_run, previous=previous, previous_unit=tree.length_unit if tree else None,
             reuse_geometry=same_settings, removed=tree.removed if tree is not None else None)
    read_seconds = time.perf_counter() - t0
    if on_read is not None:
        on_read(doc)
    tess = tessellate(doc, settings, cache=cache, progress=tessellation_progress)
    with Pusher(server, transport=transport, upload_progress=upload_progress, token=token) as pusher:
        if doc.reuse_if_same_surface:  # a B-rep close to the scene's: keep its mesh if it shows the same surface
            confirm_same_surface(doc, tess, lambda gid: pusher.geometry(gid)[:2])
        result = pusher.push(doc, tess, scene, base_revision=tree.revision if tree else None, dry_run=dry_run)
    return result, doc, tess, read_seconds, previous
