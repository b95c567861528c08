"""Ray queries on a committed scene: `Scene.intersect` and `Scene.occluded` (docs/DESIGN.md), batch after batch of rays
checked once and traced by the lanes (:func:`tracer.accel.lanes.batch`), in parallel or on the threads asked for.

`SceneQueries` is the half of `tracer.Scene` that reads what a commit published (``self.arrays()``); the scene's
own module keeps what edits it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np

from tracer.accel.lanes import batch
from tracer.errors import TracerError
from tracer.jit import njit


@dataclass(frozen=True)
class Hits:
    """Closest hits of a batch of k rays.

    Attributes
    ----------
    t : (k,) float64
        Ray parameter of the hit (``inf`` on a miss), in units of ``|d|``.
    instance : (k,) int64
        Instance id (-1 on a miss).
    primitive : (k,) int64
        Triangle index in the geometry's ``triangles`` (-1 on a miss).
    u, v : (k,) float64
        Barycentrics: ``p = (1-u-v) v0 + u v1 + v v2``.
    normal : (k, 3) float64
        Unit world-space geometric normal (zeros on a miss).
    """

    t: np.ndarray
    instance: np.ndarray
    primitive: np.ndarray
    u: np.ndarray
    v: np.ndarray
    normal: np.ndarray


class SceneQueries:
    """Closest-hit and any-hit queries of batches of rays; the class using it provides ``arrays()``."""

    def arrays(self) -> Any:   # pragma: no cover - provided by tracer.Scene
        raise NotImplementedError

    def intersect(self, origins: Any, directions: Any, t_max: Any = np.inf, *, threads: int | None = None) -> Hits:
        """Closest hits of rays ``origins[i] + t directions[i]``, ``0 < t < t_max`` (sensors ignored).

        origins, directions : (k, 3) float, world; directions need not be unit (``t`` is in units of ``|d|``).
        t_max : float or (k,) float. threads : int or None — None: numba's setting; 1 for per-core measurements.
        """
        return self._trace(origins, directions, t_max, threads, any_hit=False)

    def occluded(self, origins: Any, directions: Any, t_max: Any = np.inf, *, threads: int | None = None) -> np.ndarray:
        """(k,) bool: does any solid lie on ``origins[i] + t directions[i]``, ``0 < t < t_max``?"""
        return self._trace(origins, directions, t_max, threads, any_hit=True).instance >= 0

    def _trace(self, origins: Any, directions: Any, t_max: Any, threads: int | None, any_hit: bool) -> Hits:
        sa = self.arrays()
        o, d, tm = check_rays(origins, directions, t_max)
        k = len(o)
        h = Hits(np.empty(k), np.empty(k, np.int64), np.empty(k, np.int64), np.empty(k), np.empty(k), np.empty((k, 3)))
        run_threads(threads, lambda: batch(sa, o, d, tm, any_hit, h.t, h.instance, h.primitive, h.u, h.v, h.normal))
        return h


def run_threads(threads: int | None, fn: Callable[[], None]) -> None:
    if threads is None:
        fn()
        return
    if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) \
            or not 1 <= threads <= numba.config.NUMBA_NUM_THREADS:
        raise TracerError(f"threads must be an int in [1, {numba.config.NUMBA_NUM_THREADS}], got {threads!r}")
    old = numba.get_num_threads()
    numba.set_num_threads(int(threads))
    try:
        fn()
    finally:
        numba.set_num_threads(old)


def check_rays(origins: Any, directions: Any, t_max: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Validate a ray batch; return contiguous float64 (k,3), (k,3), (k,)."""
    arrs = []
    for name, a in (("origins", origins), ("directions", directions)):
        x = np.asarray(a)
        if x.ndim != 2 or x.shape[1] != 3:
            raise TracerError(f"{name} must have shape (k, 3), got {x.shape}")
        if not (np.issubdtype(x.dtype, np.floating) or np.issubdtype(x.dtype, np.integer)):
            raise TracerError(f"{name} must be real numbers, got dtype {x.dtype}")
        arrs.append(np.ascontiguousarray(x, dtype=np.float64))
    o, d = arrs
    if len(o) != len(d):
        raise TracerError(f"origins and directions differ in length: {len(o)} vs {len(d)}")
    try:
        tm = np.asarray(t_max, dtype=np.float64)
    except (TypeError, ValueError):
        raise TracerError(f"t_max must be a number or (k,) numbers, got {t_max!r}") from None
    if tm.ndim == 0:
        tm = np.full(len(o), float(tm))
    elif tm.shape != (len(o),):
        raise TracerError(f"t_max must be a scalar or have shape ({len(o)},), got {tm.shape}")
    tm = np.ascontiguousarray(tm)
    i, what = first_bad_ray(o, d, tm)
    if what == 1:
        raise TracerError(f"ray {i}: origin is not finite: {o[i].tolist()}")
    if what == 2:
        raise TracerError(f"ray {i}: direction is not finite: {d[i].tolist()}")
    if what == 3:
        raise TracerError(f"ray {i}: direction is zero")
    if what == 4:
        raise TracerError(f"ray {i}: t_max must be >= 0 (inf allowed), got {tm[i]}")
    return o, d, tm


@njit(cache=True, error_model="numpy")
def first_bad_ray(o, d, tm):
    """``(i, what)`` of the first bad ray (what: 1 origin not finite, 2 direction not finite, 3 zero
    direction, 4 t_max NaN or negative), ``(-1, 0)`` when all are good: one pass, where the numpy
    masks took four and cost as much as tracing a simple scene."""
    for i in range(o.shape[0]):
        if not (math.isfinite(o[i, 0]) and math.isfinite(o[i, 1]) and math.isfinite(o[i, 2])):
            return i, 1
        if not (math.isfinite(d[i, 0]) and math.isfinite(d[i, 1]) and math.isfinite(d[i, 2])):
            return i, 2
        if d[i, 0] == 0.0 and d[i, 1] == 0.0 and d[i, 2] == 0.0:
            return i, 3
        if not (tm[i] >= 0.0):
            return i, 4
    return -1, 0
