"""The optics contract tests share the light-transport tests' meshes (`tests/tracer/transport_scenes.py`): the
folder above is put on the import path, as it is when pytest collects a test file there (no package
`__init__.py` in tests/, so pytest puts each test file's own folder on the path)."""

from __future__ import annotations

import sys
from pathlib import Path

_TRACER_TESTS = str(Path(__file__).resolve().parents[1])
if _TRACER_TESTS not in sys.path:
    sys.path.insert(0, _TRACER_TESTS)
