"""Compile the kernels of a first query in other processes, before the query arrives.

numba compiles a kernel on its first call and keeps it in its on-disk cache. On a fresh install that first
call is the user's first query, which then waits for the compiler: about 40 s on 2 cores for the walk and the
forward kernel, and numba compiles one function at a time per process (its compiler lock), so a thread of the
service's own process would only queue behind the user's push. `start_background()` runs two child processes
instead, one per core, while the service compiles what the user's first push needs (bottom and top level
builders); the query then loads the kernels from the cache. Each child compiles its stages in order and
reports each on its standard output as it ends ("STAGE SECONDS KERNEL ...", the kernels it compiled):

- ``probe``: the walk of one ray, which places a query's receivers (`tracer.accel.traverse.closest_each`; it compiles
  the walk the forward kernel calls, `tracer.accel.traverse.closest_with_stacks`);
- ``optics``: every function the forward kernel calls that is a kernel of its own (the surfaces' and lights'
  switches, the media, the receivers' crossings and tallies; `forward_callees`), so that the forward kernel loads
  them instead of compiling them;
- ``forward``: the forward photon kernel (`tracer.transport.forward.forward_kernel`);
- ``kinds``: each surface kind's ``scatter``, each light kind's ``sample``, an element table's scatter
  (`kind_callees`): the kernels call them at their addresses, so none waits for them, and a query binds those its
  scene holds (until 2026-11-29 they were part of ``optics``, and the forward kernel of a first query waited for
  every kind: a grating's orders, measured BSDFs, rough glass);
- ``backward``: the backward kernel (`tracer.transport.backward.backward_batches`);
- ``scene``: the builders of a small room scene (what a later first push needs);
- ``radiance``: the luminance kernel (`tracer.transport.radiance`: paths from the eye, light tracing), by running a
  luminance meter in that room (its block glass, so that light tracing's join through glass, compiled on its own, is
  compiled too), at the lowest CPU priority (`LOW_PRIORITY`): about 50 s of a core cold, which a first luminance
  meter or camera would otherwise wait for.

Child 1 compiles probe, optics, forward, kinds; child 2 scene, kinds, optics, backward, radiance (`CHILDREN`). Both
compile the kinds and the optics, from opposite ends of the lists: each kernel the other child has already compiled is
loaded from numba's cache instead (numba looks there before it compiles), so the two share that work whatever else keeps
either core busy, and child 1 reaches the forward kernel without waiting for any kind. Child 2 starts with the scene
builders, which a service's first push needs: they take their compile lock in any process's first `tracer.Scene`, so a
push that arrives meanwhile waits for them instead of compiling them again (the demo's first push compiled them itself
for 35 s while the children compiled other things). Every stage but ``scene`` and ``radiance`` compiles by signature
(`kernel_types`) and runs nothing (`tests/tracer/test_warmup.py` checks that a first query after the children compiles
nothing). A query's first use of a kernel goes through `first_use(stage)`: it waits for that stage of this process's
child in flight, then holds the kernel's machine-wide compile lock (`compiling`) while it compiles or loads it, so that
no kernel is compiled twice, by this process or another (a second service, a Dask worker, a test worker); it goes on at
once where nothing holds it (or the children failed: then the query compiles for itself, as it would have).

A child ends when the process that started it has gone (``--parent``: it looks every half second), however that
process ended (stopped, killed, crashed): a compile for a service that no longer runs would only take the cores from
whatever runs next (until 2026-12-08 a stopped service's children compiled on for a minute, and a service started
after it, the first-answer bench's second one, reached ``/health`` in 8.3 s instead of 3).
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import threading
import time
from typing import Any

import numpy as np

from tracer import compile_locks
from tracer.compile_locks import compiling, first_use, wait_background

__all__ = ["Background", "compile_query_kernels", "compile_stage", "compiling", "first_use", "start_background",
           "wait_background"]

#: the stages each child compiles, in order, and whether it compiles the optics from the end of their list
CHILDREN = ((("probe", "optics", "forward", "kinds"), True),
            (("scene", "kinds", "optics", "backward", "radiance"), False))
STAGES = ("probe", "optics", "forward", "kinds", "backward", "scene", "radiance")
#: stages a child compiles at the lowest CPU priority (``nice``): what a first query of another kind needs, compiled
#: with what the cores have left, so that it never slows the compile a running query waits for, nor the query
LOW_PRIORITY = ("radiance",)


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


def kernel_types() -> dict[str, Any]:
    """numba types of what the query kernels take, built without compiling anything: the scene's and the
    receivers' arrays (`SceneArrays`), materials, lights, a query's sensors and disks, scalars and vectors."""
    from numba import typeof, types

    from tracer.accel.traverse import empty_scene_arrays
    from tracer.optics.lights import pack_lights
    from tracer.optics.surfaces.dispatch import pack_materials
    from tracer.transport.backward import QueryArrays
    from tracer.transport.forward import SensorArrays

    f8v = np.zeros(1)
    i8v = np.zeros(1, np.int64)
    return {"sa": typeof(empty_scene_arrays()), "mats": typeof(pack_materials({}, None, [], set())),
            "lights": typeof(pack_lights([{"type": "point", "position": [0.0, 0.0, 2.0], "intensity_cd": 1.0}])),
            "sensors": typeof(SensorArrays(i8v, i8v, i8v, i8v, np.zeros((1, 3)), i8v, f8v)),
            "disks": typeof(QueryArrays(i8v, *[np.zeros((1, 3))] * 4)),
            "i8": types.int64, "u8": types.uint64, "f8": types.float64, "vi": types.int64[::1],
            "vf": types.float64[::1], "mf": types.float64[:, ::1]}


def scatter_types(t: dict[str, Any]) -> tuple:
    """The argument types a surface's ``scatter`` gets from the forward kernel (`t`: `kernel_types`)."""
    sa, mats, i8, u8, f8, vi, vf = (t[k] for k in ("sa", "mats", "i8", "u8", "f8", "vi", "vf"))
    return (sa, mats, i8, i8, *[f8] * 8, vi, i8, u8, i8, f8, vf)


def forward_callees() -> list[tuple[Any, tuple]]:
    """``(kernel, signature)`` of every function the forward kernel (`tracer.transport.forward.trace_photons`) calls
    with the argument types the forward kernel passes: the surface and light switches (the kinds behind them are
    `kind_callees`), the media's switch, the receivers' crossings and tallies, the random numbers. Helpers that LLVM
    inlines (`tracer.jit`) are compiled on their own too, once per argument types, so they are here as well."""
    from tracer import rng
    from tracer.accel import spawn, traverse
    from tracer.optics import frames, polarization, spectra
    from tracer.optics.lights import dispatch as lights
    from tracer.optics.lights import pick_light
    from tracer.optics.media import dispatch as media
    from tracer.optics.media import homogeneous
    from tracer.optics.surfaces import dispatch as surfaces
    from tracer.transport import forward as transport

    t = kernel_types()
    sa, mats, i8, u8, f8, vi, vf, mf = (t[k] for k in ("sa", "mats", "i8", "u8", "f8", "vi", "vf", "mf"))
    scatter = scatter_types(t)
    own = [(surfaces.scatter, scatter), (surfaces.table_row, (sa, i8, i8)), (surfaces.feature_surface, (sa, i8, i8)),
           (pick_light, (t["lights"], f8)), (lights.sample_emission, (t["lights"], i8, *[f8] * 5)),
           (lights.emit_wavelength, (t["lights"], i8, f8))]
    own += [(media.medium_coefficients, (mats, i8, f8)), (media.medium_event, (mats, i8, *[f8] * 6, u8, i8, vf)),
            (homogeneous.sample_free_flight, (f8, f8)), (homogeneous.transmittance, (f8, f8)),
            (spectra.sample_grid, (vf, vf, f8)), (spectra.luminous, (f8,)), (frames.find_in_cdf, (vf, i8, i8, f8)),
            (polarization.emit, (vf, mf, i8, f8, f8, f8)),
            (traverse.sensor_crossings_with_stack, (sa, *[f8] * 7, vi, vf, vf, vf, vf, vi)),
            (transport.record_far, (vf, vf, f8, f8, f8, f8)), (transport.record_spectrum, (vf, i8, i8, f8, f8)),
            (transport.record_stokes, (vf, i8, i8, f8, vf, f8, f8, f8, mf, i8)),
            (rng.path_key, (i8, i8, i8)), (rng.uniform, (u8, i8)), (spawn.offset_ray_origin, tuple([f8] * 9))]
    return own


def kind_callees() -> list[tuple[Any, tuple]]:
    """``(kernel, signature)`` of each surface kind's ``scatter``, each light kind's ``sample`` (from their
    registrations, so a new kind is included) and an element table's scatter (a tabulated BSDF, a grating's orders):
    the kernels call them at their addresses (`tracer.jit.kind_table`), bound for the kinds a scene holds, so no
    kernel waits for them and a first query waits only for the kinds its own scene holds. With them the Mie table's
    amplitude sums, which a dielectric holding particles needs before its first photon (1.3 s)."""
    from numba import types

    from tracer.optics import mie
    from tracer.optics.lights import dispatch as lights
    from tracer.optics.surfaces import dispatch as surfaces

    t = kernel_types()
    scatter = scatter_types(t)
    sample = (t["lights"], t["i8"], *[t["f8"]] * 5)
    complexes = types.complex128[::1]
    return ([(kind.scatter, scatter) for kind in surfaces.KINDS] + [(kind.sample, sample) for kind in lights.KINDS]
            + [(surfaces.element_table_scatter, scatter),
               (mie.amplitude_sums, (complexes, complexes, types.float64[::1]))])


#: the stages whose compile `compiling` makes one process's at a time (the optics are shared kernel by kernel
#: instead, each child from its own end of the list; the scene's builders take their own lock in a process's first
#: `tracer.Scene`, the ``scene`` stage's included)
LOCKED_STAGES = ("probe", "forward", "backward")


def compile_stage(stage: str, reverse: bool = False) -> None:
    """Compile (or load) the kernels of one stage (`STAGES`): by signature, without running them, but for the
    builders of ``scene``, which run on a small room; `reverse`: the optics from the end of their list. The stages of
    `LOCKED_STAGES` under `compiling`, so that no other process compiles them at the same time."""
    with compiling(stage) if stage in LOCKED_STAGES else contextlib.nullcontext():
        _compile_stage(stage, reverse)


def _compile_stage(stage: str, reverse: bool) -> None:
    from tracer.accel.traverse import closest_each
    from tracer.scene import Scene
    from tracer.transport.backward import backward_batches
    from tracer.transport.forward import forward_kernel

    if stage in ("scene", "radiance"):
        scene = Scene()
        ids = [scene.add_instance(scene.add_geometry(*box(lo, hi)), np.eye(4))
               for lo, hi in (((0, 0, 0), (4, 4, 3)), ((1, 1, 0.5), (2, 2, 1)))]
        scene.commit()
        if stage == "radiance":   # run, not typed: its arguments are built per query (views, emitters, light paths)
            from tracer.simulate import Simulation

            # the block is glass: light tracing joins through it, so its join (`tracer.transport.through_flat`,
            # called at its address) is compiled here too
            sim = Simulation(scene, {ids[0]: {"type": "lambertian", "reflectance": 0.5},
                                     ids[1]: {"type": "dielectric", "ior": 1.5}},
                             [{"type": "point", "position": [2.0, 2.0, 2.5], "intensity_cd": 100.0}])
            sim.run({"type": "luminance", "position": [3.5, 3.5, 1.5], "direction": [-1.0, -1.0, -1.0]},
                    max_photons=200)
        return
    if stage in ("optics", "kinds"):
        callees = forward_callees() if stage == "optics" else kind_callees()
        for kernel, signature in reversed(callees) if reverse else callees:
            kernel.compile(signature)
        return
    t = kernel_types()
    sa, mats, lights, i8, vf, vi, mf = (t[k] for k in ("sa", "mats", "lights", "i8", "vf", "vi", "mf"))
    if stage == "probe":
        closest_each.compile((sa, mf, mf, vf, vf, vi, mf))
    elif stage == "forward":
        forward_kernel("white").compile((sa, sa, mats, lights, t["sensors"], i8, i8, i8, i8, i8))
    elif stage == "backward":
        backward_batches.compile((sa, mats, lights, t["disks"], i8, i8, i8, i8))
    else:
        raise ValueError(f"no warm-up stage {stage!r}; the stages are {', '.join(STAGES)}")


def compile_query_kernels(report=print, stages=STAGES, reverse: bool = False, nice: int = 0) -> None:
    """Compile (or load) the kernels of `stages` in order; `report(line)` says "STAGE SECONDS KERNEL ..." after
    each: the kernels it compiled (not those it loaded), by module and name. `nice` > 0: this process's CPU
    priority is lowered by that much before the first stage of `LOW_PRIORITY` (for good: a child's last stages)."""
    from numba.core import event

    compiled: list[str] = []

    class Compiles(event.Listener):
        def on_start(self, ev):
            f = ev.data["dispatcher"].py_func
            compiled.append(f"{f.__module__}.{f.__qualname__}")

        def on_end(self, ev):
            pass

    with event.install_listener("numba:compile", Compiles()):
        for stage in stages:
            if nice > 0 and stage in LOW_PRIORITY and hasattr(os, "nice"):
                os.nice(nice)
                nice = 0
            t = time.perf_counter()
            compiled.clear()
            compile_stage(stage, reverse)
            report(" ".join([stage, f"{time.perf_counter() - t:.3f}", *dict.fromkeys(compiled)]))


class Background:
    """The child processes compiling the query kernels (`CHILDREN`); `wait(stage)` until that stage is compiled (or
    every child that compiles it has ended)."""

    def __init__(self, children=CHILDREN, nice: int = 10) -> None:
        """`children`: the stages of each child (`CHILDREN`); `nice`: how much lower the CPU priority of the
        `LOW_PRIORITY` stages is (0: as the service's)."""
        self.seconds: dict[str, float] = {}
        self.stages = tuple(dict.fromkeys(stage for stages, _ in children for stage in stages))
        #: the kernels each stage compiled (in either child)
        self.compiled: dict[str, list[str]] = {}
        self._events = {stage: threading.Event() for stage in self.stages}
        self._left = {stage: sum(stage in stages for stages, _ in children) for stage in self.stages}
        self._lock = threading.Lock()
        self._procs: list[subprocess.Popen] = []
        for stages, reverse in children:
            proc = subprocess.Popen([sys.executable, "-m", "tracer.warmup", *(["--reverse"] if reverse else []),
                                     f"--nice={nice}", f"--parent={os.getpid()}", *stages], stdout=subprocess.PIPE,
                                    stderr=subprocess.DEVNULL, text=True)
            self._procs.append(proc)
            threading.Thread(target=self._read, args=(proc, stages), name="lumenlink-warmup", daemon=True).start()

    def _read(self, proc: subprocess.Popen, stages: tuple[str, ...]) -> None:
        assert proc.stdout is not None
        done = set()
        for line in proc.stdout:
            stage, seconds, *compiled = line.split() or [""]
            if stage in stages:
                done.add(stage)
                self.seconds.setdefault(stage, float(seconds))
                self.compiled.setdefault(stage, []).extend(compiled)
                self._events[stage].set()
        proc.wait()
        with self._lock:
            for stage in set(stages) - done:   # this child ended without it: no use waiting for it any longer
                self._left[stage] -= 1         # unless the other child may still do it
                if self._left[stage] == 0:
                    self._events[stage].set()

    def wait(self, stage: str, timeout: float | None = None) -> bool:
        """Wait until `stage` is compiled or every child compiling it has ended; False on timeout. A kernel no child
        compiles (not one of its stages) has nothing to wait for."""
        event = self._events.get(stage)
        return True if event is None else event.wait(timeout)

    def status(self) -> dict:
        """{"state": "warming" | "ready" | "failed", "seconds": {stage: s}} for `GET /health`."""
        codes = [proc.poll() for proc in self._procs]
        if None in codes:
            state = "warming"
        else:
            state = "ready" if not any(codes) and len(self.seconds) == len(self.stages) else "failed"
        return {"state": state, "seconds": dict(self.seconds)}

    def join(self, timeout: float | None = None) -> int:
        """Wait for the children to end; the first non-zero exit status, or 0."""
        codes = [proc.wait(timeout) for proc in self._procs]
        return next((code for code in codes if code), 0)

    def stop(self, timeout: float = 10.0) -> None:
        """Kill the children still compiling and wait (up to `timeout` s each) until they have ended, so that nothing
        writes into numba's cache once this returns."""
        for proc in self._procs:
            if proc.poll() is None:
                proc.kill()
        for proc in self._procs:
            with contextlib.suppress(subprocess.TimeoutExpired):
                proc.wait(timeout)


_BACKGROUND: Background | None = None


def start_background() -> Background:
    """Start compiling the query kernels in child processes (once per process); returns their handle."""
    global _BACKGROUND
    if _BACKGROUND is None:
        _BACKGROUND = Background()
        compile_locks.waits_for(_BACKGROUND)
    return _BACKGROUND


def exit_with_parent(parent: int, every: float = 0.5) -> threading.Thread:
    """End this process (exit status 0) as soon as process `parent`, which started it, has gone: its parent id is no
    longer `parent` (an orphan is handed to another), checked every `every` seconds on a daemon thread."""
    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(every)
        os._exit(0)   # numba writes each cache entry to a temporary file and renames it: none is left half written

    thread = threading.Thread(target=watch, name="lumenlink-warmup-parent", daemon=True)
    thread.start()
    return thread


def main(args: list[str]) -> None:
    """A child: ``python -m tracer.warmup [--reverse] [--nice=N] [--parent=PID] [STAGE ...]`` compiles the stages
    named (all of `STAGES` where none is), the optics from the end of their list with ``--reverse``, the
    `LOW_PRIORITY` ones N lower in CPU priority; with ``--parent``, only as long as process PID, which started it,
    runs (`exit_with_parent`)."""
    options = {a.split("=", 1)[0]: a.split("=", 1)[1] for a in args if a.startswith("--") and "=" in a}
    reverse = "--reverse" in args
    nice = int(options.get("--nice", 0))
    if "--parent" in options:
        exit_with_parent(int(options["--parent"]))
    stages = tuple(a for a in args if not a.startswith("--")) or STAGES
    compile_query_kernels(report=lambda line: print(line, flush=True), stages=stages, reverse=reverse, nice=nice)


if __name__ == "__main__":
    main(sys.argv[1:])
