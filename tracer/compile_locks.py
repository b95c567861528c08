"""A kernel's first compile, one process at a time: who waits for whom before numba compiles (or loads) a kernel.

numba compiles a kernel on its first call in a process and keeps it in its on-disk cache; two processes that meet the
same kernel at once both compile it (a cold forward kernel is about 2 minutes of a core). `first_use(kernel)` goes
around a kernel's first call: it waits for this process's warm-up child compiling that stage, if any
(`tracer.warmup.Background`, registered by `waits_for`), then holds the kernel's machine-wide lock (`compiling`) while
the call compiles or loads it, so that another process (a warm-up child, a second service, a Dask worker, a test
worker) waits and loads it from the cache instead. Nothing here imports the rest of the tracer: the query code
(`tracer.transport.rounds`, `tracer.sensors.placement`) and the warm-up (`tracer.warmup`) both use it.
"""

from __future__ import annotations

import contextlib
import logging
import os
import time
from collections.abc import Iterator
from typing import Any

log = logging.getLogger(__name__)

#: this process's warm-up children (`tracer.warmup.Background`), once started: anything with ``wait(stage, timeout)``
_BACKGROUND: Any = None
#: kernels this process has used once already: later uses take no lock (a query's probe is not a lock file per call)
_USED: set[str] = set()


def waits_for(background: Any) -> None:
    """From now on a first use waits for `background`'s stage of the same name (``background.wait(stage, timeout)``)."""
    global _BACKGROUND
    _BACKGROUND = background


def wait_background(stage: str, timeout: float = 600.0) -> None:
    """Before a kernel's first use: wait for this process's child compiling it, if there is one."""
    if _BACKGROUND is not None:
        _BACKGROUND.wait(stage, timeout)


@contextlib.contextmanager
def compiling(kernel: str, timeout: float = 600.0, poll: float = 0.1) -> Iterator[None]:
    """Hold the machine-wide lock of a kernel's first compile (or load) in this process: a second process that needs
    the same kernel meanwhile (a warm-up child, a second service, a Dask worker, a test worker) waits for it and
    then loads it from numba's cache instead of compiling it too (a cold forward kernel is about 2 minutes of a core).

    The lock is ``flock`` on ``<numba cache>/compiling-<kernel>.lock``; where there is no cache directory or no
    ``fcntl``, or the lock is still held after `timeout` seconds, it goes on without (numba's own cache writes stay
    atomic, so the worst is the compile done twice)."""
    try:
        import fcntl

        from numba.core import config
        folder = config.CACHE_DIR or os.environ.get("NUMBA_CACHE_DIR", "")
        if not folder:
            raise OSError("no numba cache directory")
        os.makedirs(folder, exist_ok=True)
        handle = open(os.path.join(folder, f"compiling-{kernel}.lock"), "a")   # noqa: SIM115 - held below
    except (ImportError, OSError):
        yield
        return
    try:
        t0 = time.monotonic()
        while True:
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() - t0 > timeout:
                    log.warning("the %s kernel's compile lock is still held after %.0f s: compiling it here too",
                                kernel, timeout)
                    break
                time.sleep(poll)
        yield
    finally:
        handle.close()   # releases the lock


@contextlib.contextmanager
def first_use(kernel: str, timeout: float = 600.0) -> Iterator[None]:
    """Around a kernel's first call in this process: wait for this process's child compiling it (`wait_background`),
    then hold the kernel's machine-wide compile lock (`compiling`) while the call compiles or loads it. In that order:
    a child needs the same lock to compile the stage being waited for. Later uses go straight through."""
    if kernel in _USED:
        yield
        return
    wait_background(kernel, timeout)
    with compiling(kernel, timeout):
        yield
    _USED.add(kernel)
