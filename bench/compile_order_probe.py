"""How fast the luminance kernel runs depending on how it was compiled (issue 49's finding of 2026-12-07).

The same source answered the diffuse room's 80 x 60 camera, 480,000 paths on one thread, in 1.0 s from a numba cache
filled by ``bench/bench_luminance_compile.py`` (a backward lux query compiled first, then a meter) and in 3.0 s from a
cache filled by this script's own first query (the camera compiled cold). To see it::

    XDG_CACHE_HOME=/tmp/cold .venv/bin/python bench/compile_order_probe.py
    XDG_CACHE_HOME=/tmp/warm .venv/bin/python bench/bench_luminance_compile.py
    XDG_CACHE_HOME=/tmp/warm .venv/bin/python bench/compile_order_probe.py

(each with an empty cache directory the first time). It prints the seconds of two runs of the same query.
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
