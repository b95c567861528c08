"""DESIGN.md's geometry id, from ``tracer/geometry_id.py`` without importing the ``tracer`` package.

``import tracer.geometry_id`` runs ``tracer/__init__``, which loads numba and the whole ray tracer: seconds
of start-up for a ``lumenlink push`` that only needs a SHA-256, and a CAD push that breaks whenever the
tracer does. The module file is pure numpy and hashlib, so it is loaded on its own, under a private
name; it is the very same source, so the ids cannot drift apart.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path


def _load():
    name = "cad_adapter._tracer_geometry_id"
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.find_spec("tracer")
    path = Path(spec.origin).parent / "geometry_id.py" if spec and spec.origin else None
    if path is None or not path.exists():  # an unusual install: fall back on the package import
        import tracer.geometry_id as module

        return module
    file_spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(file_spec)
    sys.modules[name] = module
    file_spec.loader.exec_module(module)
    return module


_module = _load()
canonical_arrays = _module.canonical_arrays
geometry_id = _module.geometry_id
is_geometry_id = _module.is_geometry_id
