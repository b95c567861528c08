"""The tracer on a CUDA GPU through numba-cuda (issue 27; the optional extra ``lumenlink[gpu]``).

Import numba-cuda only through :func:`cuda`: it is the one place that makes numba-cuda importable with the numpy
this project runs on (see below), and a CPU-only install never imports it.

numpy 2.5 removed ``np.row_stack`` (an alias of ``np.vstack`` since numpy 2.0); numba-cuda 0.30.4 still calls it
when it compiles a kernel, so on numpy >= 2.5 every kernel compile fails with an AttributeError (measured on the
device image: numba 0.68.0, numba-cuda 0.30.4, numpy 2.5.2). :func:`cuda` restores the alias, only where numpy
lacks it, before numba-cuda is imported. Remove this once numba-cuda no longer calls it.
"""

from __future__ import annotations

import numpy as np


def _restore_row_stack() -> None:
    """``np.row_stack = np.vstack`` where numpy (>= 2.5) no longer has it: numba-cuda 0.30.4 still calls it."""
    if not hasattr(np, "row_stack"):
        np.row_stack = np.vstack  # type: ignore[attr-defined]


def cuda():
    """The ``numba.cuda`` module, imported after the numpy shim above; ImportError where numba-cuda is not installed
    (``pip install 'lumenlink[gpu]'``)."""
    _restore_row_stack()
    from numba import cuda as numba_cuda

    return numba_cuda
