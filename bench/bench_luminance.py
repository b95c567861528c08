"""Camera images of a diffuse room (a 4 × 4 × 2.5 m box of ρ = 0.5, one 1000 cd point source near the ceiling):
seconds to the first image and the median pixel relative error as the budget grows, on this machine.

    NUMBA_CACHE_DIR=... python bench/bench_luminance.py [width height]
"""
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from tests.tracer.transport_scenes import box, scene_of  # noqa: E402
from tracer.simulate import Simulation  # noqa: E402

w, h = (int(sys.argv[1]), int(sys.argv[2])) if len(sys.argv) > 2 else (160, 120)
s, ids = scene_of(box([-2, -2, 0], [2, 2, 2.5]))
sim = Simulation(s, {ids[0]: {"type": "lambertian", "reflectance": 0.5}},
                 [{"type": "point", "position": [0.2, -0.1, 2.2], "intensity_cd": 1000.0}])
cam = {"type": "camera", "position": [-1.8, -1.8, 1.6], "look_at": [1.0, 1.0, 0.8], "fov_deg": 60, "width": w,
       "height": h}
sim.run({**cam, "width": 2, "height": 2}, max_photons=100)   # compile or load the kernel first
for budget in (0.2, 1.0, 4.0, 16.0):
    t = time.perf_counter()
    r = sim.run(cam, max_seconds=budget, seed=1)
    rel = r.stderr / np.where(r.luminance > 0, r.luminance, np.nan)
    print(f"{w}x{h} budget {budget:5.1f} s: {time.perf_counter() - t:6.2f} s, {r.photons:>10} paths, "
          f"{r.batches} batches, median pixel relative error {np.nanmedian(rel):.4f}, "
          f"mean luminance {r.luminance.mean():.2f} cd/m²")
