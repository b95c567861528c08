"""`tracer.jit`: a kernel called with literal constants compiles once, for the arguments' types."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

CHILD = """
import numpy as np
from numba import njit
from tracer.rng import uniform

@njit
def three_draws(key):
    return uniform(key, 0) + uniform(key, 1) + uniform(key, 5)

three_draws(np.uint64(7))
print(len(uniform.signatures), *uniform.signatures)
"""


def test_literal_arguments_do_not_compile_a_kernel_again(tmp_path):
    """numba alone compiles `uniform` three times here (Literal[int](0), (1), (5)); the tracer's njit once, for
    (uint64, int64). A fresh numba cache, so nothing is loaded from an earlier run."""
    r = subprocess.run([sys.executable, "-c", CHILD], cwd=ROOT, capture_output=True, text=True, timeout=300,
                       env={"PATH": "/usr/bin:/bin", "NUMBA_CACHE_DIR": str(tmp_path), "PYTHONPATH": str(ROOT)})
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.split() == ["1", "(uint64,", "int64)"], r.stdout
