"""How fast the luminance kernel runs depending on how it was compiled (issue 49's finding of 2026-12-07).

The same source answered the diffuse room's 80 x 60 camera, 480,000 paths on one thread, in 1.0 s from a numba cache
filled by ``bench/bench_luminance_compile.py`` (a backward lux query compiled first, then a meter) and in 3.0 s from a
cache filled by this script's own first query (the camera compiled cold). To see it::

    XDG_CACHE_HOME=/tmp/cold .venv/bin/python bench/compile_order_probe.py
    XDG_CACHE_HOME=/tmp/warm .venv/bin/python bench/bench_luminance_compile.py
    XDG_CACHE_HOME=/tmp/warm .venv/bin/python bench/compile_order_probe.py

(each with an empty cache directory the first time). It prints the seconds of two runs of the same query.

The cause (found 2026-12-07 with ``perf record`` on the kernel's code and the symbols of its cached object file): the
machine code of the two caches was the same function for function, within a few instructions; what differed was how
long one stretch of it took. ``radiance_batch`` called ``trace_view`` once a path with the scene's, the materials',
the lights' and the views' tuples by value: numba flattens each array of a tuple into its seven words, so each call
stored 3,440 bytes of arguments on the stack (826 moves), and 67 % of the slow kernel's samples (28 % of the fast
one's) sat on those moves: how fast a run of stores and reloads through the same stack slots goes depends on the
frame's layout, which each compile lays out anew. ``trace_view`` and the light sample at each vertex
(``light_sample``; ``trace_path`` and ``direct_illuminance`` in the backward kernel, ``join_eye`` in light tracing)
are now LLVM-inlined into their callers (``inline="always"``, which ``tracer.jit.njit`` makes ``forceinline``): no
per-path or per-vertex call passes the tuples. The same 480,000 paths now take 1.0-1.3 s whichever order compiled
them (0.22x the camera-first cache's time, ``bench/ab.py ... room camera 6``), the backward lux kernel 0.61x
(``room lux 8``), every answer bit-identical (``bench/answers_snapshot.py``), the luminance kernel's cold compile
28.5 -> 30.0 s.
"""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numba  # noqa: E402

from bench.bench_luminance import camera  # noqa: E402
from bench.bench_transport import INTENSITY, LIGHT, RHO, room_scene  # noqa: E402
from tracer.simulate import Simulation  # noqa: E402

numba.set_num_threads(1)
s, room = room_scene()
sim = Simulation(s, {room: {"type": "lambertian", "reflectance": RHO}},
                 [{"type": "point", "position": list(LIGHT), "intensity_cd": INTENSITY}])
sim.run(camera(2, 2), max_photons=64)   # compile (or load) the kernel
for k in range(2):
    r = sim.run(camera(80, 60), max_photons=480_000, seed=k + 1)
    print(f"run {k}: {int(r.photons):,} paths in {r.seconds:.2f} s")
