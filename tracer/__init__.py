"""tracer: two-level ray tracing (per-object bottom levels, a top level over instances) in numba.

Public API (docs/DESIGN.md): :class:`Scene`, :class:`UpdateStats`, :class:`Hits`, :class:`TracerError`,
and the module :mod:`tracer.geometry_id` (the content hash). Jitted kernels for light transport live
in :mod:`tracer.accel.traverse` and :mod:`tracer.accel.spawn` (docs/CONTRACTS.md).

The names are loaded on first use (PEP 562), so ``import tracer.geometry_id`` (the CAD adapter's only
need: a SHA-256 over numpy arrays) does not load numba and the kernels.
"""

from __future__ import annotations

import hashlib
import importlib
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from tracer.errors import TracerError
    from tracer.scene import Hits, Scene, UpdateStats

_WHERE = {"TracerError": "tracer.errors", "Hits": "tracer.scene", "Scene": "tracer.scene",
          "UpdateStats": "tracer.scene"}

__all__ = ["Hits", "Scene", "TracerError", "UpdateStats"]


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        return getattr(importlib.import_module(_WHERE[name]), name)
    raise AttributeError(f"module 'tracer' has no attribute {name!r}")


def numba_cache_dir(root: Path = Path(__file__).parent) -> Path:
    """A numba cache directory keyed by the content of every tracer source file.

    numba checks a cached kernel against its own file only: a kernel compiled with a callee from
    another module (``transport`` calling ``sources``) would outlive an edit of that callee and run
    the old code. Keying the directory by all tracer sources makes any edit start a fresh cache.
    """
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(path.relative_to(root).as_posix().encode() + b"\0" + path.read_bytes())
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "lumenlink" / "numba" / digest.hexdigest()[:16]


if not os.environ.get("NUMBA_CACHE_DIR"):  # a directory the user chose is left alone
    if "numba" in sys.modules:
        sys.modules["numba"].config.CACHE_DIR = str(numba_cache_dir())
    else:
        os.environ["NUMBA_CACHE_DIR"] = str(numba_cache_dir())
