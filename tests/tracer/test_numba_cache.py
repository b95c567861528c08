"""Compiled kernels are cached under a directory keyed by every tracer source, so no edit runs stale code."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import tracer

TRACER = Path(tracer.__file__).resolve().parent


def test_any_edit_of_any_tracer_source_changes_the_cache_directory(tmp_path) -> None:
    copy = tmp_path / "tracer"
    shutil.copytree(TRACER, copy, ignore=shutil.ignore_patterns("__pycache__"))
    before = tracer.numba_cache_dir(copy)
    assert before == tracer.numba_cache_dir(TRACER)  # the key is the content, not the location
    sources = copy / "optics" / "lights" / "point.py"  # a callee of the transport kernels, in a nested package
    sources.write_text(sources.read_text() + "\n# an edit\n")
    assert tracer.numba_cache_dir(copy) != before


def run_python(code: str, **env: str) -> str:
    environment = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"} | env
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                          env=environment).stdout.strip()


def test_kernels_use_the_keyed_directory_unless_the_user_chose_one(tmp_path) -> None:
    code = "import tracer.transport.forward, numba; print(numba.config.CACHE_DIR)"
    assert run_python(code) == str(tracer.numba_cache_dir())
    assert run_python(code, NUMBA_CACHE_DIR=str(tmp_path)) == str(tmp_path)
    # numba imported first: the setting still reaches the kernels compiled after
    assert run_python("import numba, tracer.transport.forward; print(numba.config.CACHE_DIR)") == str(
        tracer.numba_cache_dir())
