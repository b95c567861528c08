"""Compile the kernels of a first query in another process, before the query arrives.

numba compiles a kernel on its first call and keeps it in its on-disk cache. On a fresh install that first
call is the user's first query, which then waits for the compiler: about a minute on 2 cores, and numba
compiles one function at a time per process (its compiler lock), so a thread of the service's own process
would only queue behind the user's push. `start_background()` runs `compile_query_kernels` in a child
process instead, on the second core, while the service compiles what the user's first push needs (bottom
and top level builders); the query then loads the kernels from the cache. The child compiles in stages,
each reported on its standard output as it ends:

- ``probe``: the walk of one ray, which places a query's receivers (`tracer.traverse.closest_each`);
- ``forward``: the forward photon kernel (`tracer.transport.forward_kernel`, photon state "white");
- ``backward``: the backward kernel (`tracer.backward.backward_batches`);
- ``scene``: the builders of a small room scene (what a later first push needs).

It needs no scene to compile the query kernels: a scene holding only receivers has the very same array
types as any scene (`tests/tracer/test_warmup.py` checks it), so the kernels are called on that. A query
calls `wait_background(stage)` before a kernel's first use: it waits for that stage of a child in flight,
so no kernel is compiled twice, and returns at once where there is none (or it failed: then the query
compiles for itself, as it would have).
"""

from __future__ import annotations

import subprocess
import sys
import threading
import time

import numpy as np

STAGES = ("probe", "forward", "backward", "scene")


def box(lo, hi):
    """An axis-aligned box from corner lo to corner hi: (8, 3) vertices, (12, 3) triangles facing outward."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    v = np.array([[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0],
                  [x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]], float)
    t = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                  [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])
    return v, t


def receivers_only():
    """The arrays of a scene holding two receivers (a disk and a grid) and nothing else."""
    from tracer.scene import Scene

    receivers = Scene()
    receivers.add_disk_sensor([0.0, 0.0, 1.0], [0.0, 0.0, 1.0], 0.1)
    receivers.add_rect_sensor([-1.0, -1.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0])
    receivers.commit()
    return receivers.arrays()


def compile_query_kernels(report=print) -> None:
    """Compile (or load) every kernel of a first query, stage by stage; `report(line)` says "STAGE SECONDS"."""
    from tracer.backward import backward_batches, disk_queries
    from tracer.optics.lights import pack_lights
    from tracer.optics.surfaces.dispatch import pack_materials
    from tracer.scene import Scene
    from tracer.transport import SensorArrays, forward_kernel
    from tracer.traverse import closest_each

    t = time.perf_counter()
    ra = receivers_only()
    o, d = np.array([[0.0, 0.0, 2.0]]), np.array([[0.0, 0.0, -1.0]])
    closest_each(ra, o, d, np.full(1, np.inf), np.empty(1), np.empty(1, np.int64), np.empty((1, 3)))
    report(f"probe {time.perf_counter() - t:.3f}")
    t = time.perf_counter()
    mats = pack_materials({}, None, [], set())
    lights = pack_lights([{"type": "point", "position": [0.0, 0.0, 2.0], "intensity_cd": 1.0}])
    sens = SensorArrays(np.array([0, 1], np.int64), np.array([1, 4], np.int64), np.array([1, 4], np.int64),
                        np.zeros(2, np.int64), np.zeros((2, 3)))
    forward_kernel("white")(ra, ra, mats, lights, sens, 17, 0, 0, 1, 1)
    report(f"forward {time.perf_counter() - t:.3f}")
    t = time.perf_counter()
    backward_batches(ra, mats, lights, disk_queries(o, -d, 0.1), 0, 0, 1, 1)
    report(f"backward {time.perf_counter() - t:.3f}")
    t = time.perf_counter()
    scene = Scene()
    for lo, hi in (((0, 0, 0), (4, 4, 3)), ((1, 1, 0.5), (2, 2, 1))):
        scene.add_instance(scene.add_geometry(*box(lo, hi)), np.eye(4))
    scene.commit()
    report(f"scene {time.perf_counter() - t:.3f}")


class Background:
    """A child process compiling the query kernels; `wait(stage)` until it has done that stage (or ended)."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self._events = {stage: threading.Event() for stage in STAGES}
        self._proc = subprocess.Popen([sys.executable, "-m", "tracer.warmup"], stdout=subprocess.PIPE,
                                      stderr=subprocess.DEVNULL, text=True)
        threading.Thread(target=self._read, name="lumenlink-warmup", daemon=True).start()

    def _read(self) -> None:
        assert self._proc.stdout is not None
        for line in self._proc.stdout:
            stage, _, seconds = line.strip().partition(" ")
            if stage in self._events:
                self.seconds[stage] = float(seconds)
                self._events[stage].set()
        self._proc.wait()
        for event in self._events.values():   # ended (or failed): nobody waits any longer
            event.set()

    def wait(self, stage: str, timeout: float | None = None) -> bool:
        """Wait until `stage` is compiled or the child has ended; False on timeout."""
        return self._events[stage].wait(timeout)

    def status(self) -> dict:
        """{"state": "warming" | "ready" | "failed", "seconds": {stage: s}} for `GET /health`."""
        code = self._proc.poll()
        if code is None:
            state = "warming"
        else:
            state = "ready" if code == 0 and len(self.seconds) == len(STAGES) else "failed"
        return {"state": state, "seconds": dict(self.seconds)}

    def join(self, timeout: float | None = None) -> int:
        """Wait for the child to end; its exit status."""
        return self._proc.wait(timeout)

    def stop(self) -> None:
        if self._proc.poll() is None:
            self._proc.kill()


_BACKGROUND: Background | None = None


def start_background() -> Background:
    """Start compiling the query kernels in a child process (once per process); returns its handle."""
    global _BACKGROUND
    if _BACKGROUND is None:
        _BACKGROUND = Background()
    return _BACKGROUND


def wait_background(stage: str, timeout: float = 600.0) -> None:
    """Before a kernel's first use: wait for the child compiling it, if there is one."""
    if _BACKGROUND is not None:
        _BACKGROUND.wait(stage, timeout)


if __name__ == "__main__":
    compile_query_kernels(report=lambda line: print(line, flush=True))
