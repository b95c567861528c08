"""One child of `bench/bench_compile.py`: in a fresh process (the caller gives it an empty ``NUMBA_CACHE_DIR``), run
the first steps of a new user's session and say where numba's time went in each.

Usage: ``python bench/compile_probe.py STEP [STEP ...]``; prints one JSON object. Steps, in the order a user meets
them: ``scene`` (commit a room: the bottom- and top-level builders), ``forward`` (a forward lux query), ``backward``
(a backward one), ``luminance`` (a luminance meter: paths from the eye), ``camera`` (a 16×12 image); then, for a
warm install (a second process on the cache the first filled), ``novel-lux`` (a room with effects the first never
met: rough metal, Mie particles in glass; its first forward lux) and ``novel-image`` (the first camera of a room
with a mirror and a glass block: a camera answers Lambertian, specular and Fresnel scenes only). Each step's
figure is its wall seconds and, from numba's own events (`numba.core.event`), the seconds spent in each phase,
counted exclusively (a callee compiled while its caller was being typed counts for the callee, not twice):
``typing`` (type inference), ``lowering`` (numba IR to LLVM IR), ``llvm`` (LLVM's optimisation and code generation,
the time numba holds its LLVM lock), ``other`` (numba's remaining passes). The same seconds per compiled function
(``functions``: module.qualname → phases) say what each kind's own functions cost.
"""

from __future__ import annotations

import json
import os
import sys
import time
from collections import defaultdict
from pathlib import Path

#: the checkout whose tracer is compiled: this one, or another named by LUMENLINK_PROBE_ROOT (an older commit's
#: worktree, for a side-by-side run in `bench/bench_compile.py`)
ROOT = Path(os.environ.get("LUMENLINK_PROBE_ROOT") or Path(__file__).resolve().parents[1])
sys.path.insert(0, str(ROOT))

from numba.core import event  # noqa: E402

PHASE_OF_PASS = {"nopython_type_inference": "typing", "native_lowering": "lowering"}


class PhaseTimer(event.Listener):
    """Exclusive seconds per (function, phase), from nested numba events on one thread."""

    def __init__(self) -> None:
        self.stack: list[list] = []                 # [phase, function, start, children seconds]
        self.seconds: dict[tuple[str, str], float] = defaultdict(float)
        self.function = ["(outside)"]

    def on_start(self, ev):
        if ev.kind == "numba:compile":
            f = ev.data["dispatcher"].py_func
            self.function.append(f"{f.__module__}.{f.__qualname__}")
            phase = "other"
        elif ev.kind == "numba:llvm_lock":
            phase = "llvm"
        else:
            name = ev.data.get("name", "").split(" [")[0]
            phase = PHASE_OF_PASS.get(name, "other")
        self.stack.append([phase, self.function[-1], time.perf_counter(), 0.0])

    def on_end(self, ev):
        if not self.stack:
            return
        phase, function, start, children = self.stack.pop()
        spent = time.perf_counter() - start
        self.seconds[(function, phase)] += spent - children
        if self.stack:
            self.stack[-1][3] += spent
        if ev.kind == "numba:compile":
            self.function.pop()


def room():
    """A 4 × 4 × 3 m Lambertian room with a box on its floor, a point light; the simulation and its floor point."""
    import numpy as np

    from tracer.scene import Scene
    from tracer.simulate import Simulation
    from tracer.warmup import box

    scene = Scene()
    ids = [scene.add_instance(scene.add_geometry(*box(lo, hi)), np.eye(4))
           for lo, hi in (((0, 0, 0), (4, 4, 3)), ((1, 1, 0), (2, 2, 1)))]
    scene.commit()
    mats = {i: {"type": "lambertian", "reflectance": 0.5} for i in ids}
    return Simulation(scene, mats, [{"type": "point", "position": [2.0, 2.0, 2.5], "intensity_cd": 100.0}])


def novel_room():
    """The room with effects the room of `room` never met: a block of rough metal (``microfacet``) and a glass block
    holding Mie particles (spectral light), the same point light; the simulation."""
    import numpy as np

    from tracer.scene import Scene
    from tracer.simulate import Simulation
    from tracer.warmup import box

    scene = Scene()
    ids = [scene.add_instance(scene.add_geometry(*box(lo, hi)), np.eye(4))
           for lo, hi in (((0, 0, 0), (4, 4, 3)), ((1, 1, 0), (2, 2, 1)), ((2.5, 1, 0), (3.5, 2, 0.6)))]
    scene.commit()
    mats = {ids[0]: {"type": "lambertian", "reflectance": 0.5},
            ids[1]: {"type": "microfacet", "alpha": 0.3, "reflectance": 0.9},
            # the medium's fields on the dielectric: the form older trees (`bench_compile`'s "before" rows) read too
            ids[2]: {"type": "dielectric", "ior": 1.5,
                     "particles": {"radius_um": 0.5, "ior": [1.59, 0.0], "number_per_m3": 1e15}}}
    return Simulation(scene, mats, [{"type": "point", "position": [2.0, 2.0, 2.5], "intensity_cd": 100.0}])


def mirror_room():
    """The room with what paths from the eye follow beyond a Lambertian room: a mirror and a glass block (specular,
    Fresnel); the simulation. (A camera answers only such scenes: Mie particles are refused, `VIEW_EFFECTS`.)"""
    import numpy as np

    from tracer.scene import Scene
    from tracer.simulate import Simulation
    from tracer.warmup import box

    scene = Scene()
    ids = [scene.add_instance(scene.add_geometry(*box(lo, hi)), np.eye(4))
           for lo, hi in (((0, 0, 0), (4, 4, 3)), ((3.9, 1, 0.5), (3.95, 3, 2.5)), ((1, 1, 0), (2, 2, 1)))]
    scene.commit()
    mats = {ids[0]: {"type": "lambertian", "reflectance": 0.5}, ids[1]: {"type": "mirror", "reflectance": 0.9},
            ids[2]: {"type": "dielectric", "ior": 1.5}}
    return Simulation(scene, mats, [{"type": "point", "position": [2.0, 2.0, 2.5], "intensity_cd": 100.0}])


def main(steps: list[str]) -> dict:
    t0 = time.perf_counter()
    import tracer.simulate  # noqa: F401  (imports counted apart)

    out: dict = {"import_seconds": time.perf_counter() - t0, "steps": {}}
    sim = None
    for step in steps:
        timer = PhaseTimer()
        t = time.perf_counter()
        with event.install_listener("numba:compile", timer), event.install_listener("numba:run_pass", timer), \
                event.install_listener("numba:llvm_lock", timer):
            if step == "scene" or sim is None:
                sim = room()
            if step == "forward":
                sim.illuminance([[3.0, 3.0, 0.0]], [[0, 0, 1]], max_photons=2000, estimator="forward")
            elif step == "backward":
                sim.illuminance([[3.0, 3.0, 0.0]], [[0, 0, 1]], max_photons=200, estimator="backward")
            elif step == "luminance":
                sim.run({"type": "luminance", "position": [3.5, 3.5, 1.5], "direction": [-1, -1, -1]},
                        max_photons=200)
            elif step == "camera":
                sim.run({"type": "camera", "position": [3.5, 3.5, 1.5], "look_at": [2.0, 2.0, 0.5], "fov_deg": 40.0,
                         "width": 16, "height": 12}, max_photons=200)
            elif step == "novel-lux":
                sim = novel_room()
                sim.illuminance([[3.0, 3.0, 0.0]], [[0, 0, 1]], max_photons=2000, estimator="forward")
            elif step == "novel-image":
                sim = mirror_room()
                sim.run({"type": "camera", "position": [3.5, 3.5, 1.5], "look_at": [2.0, 2.0, 0.5], "fov_deg": 40.0,
                         "width": 16, "height": 12}, max_photons=200)
            elif step != "scene":
                raise SystemExit(f"unknown step {step!r}; steps: scene forward backward luminance camera "
                                 "novel-lux novel-image")
        phases: dict[str, float] = defaultdict(float)
        functions: dict[str, dict[str, float]] = defaultdict(dict)
        for (function, phase), s in timer.seconds.items():
            phases[phase] += s
            functions[function][phase] = round(s, 4)
        out["steps"][step] = {"seconds": time.perf_counter() - t, "phases": dict(phases),
                              "functions": dict(functions)}
    return out


if __name__ == "__main__":
    print(json.dumps(main(sys.argv[1:] or ["scene", "forward", "backward", "luminance", "camera"])))
