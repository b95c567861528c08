"""Compile cost of a first luminance query: the rest of the tracer loaded from numba's cache (a backward lux
query first), then a luminance meter; prints the seconds each spent compiling or loading its kernel."""
import sys
import time

sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parents[1]))
from tests.tracer.transport_scenes import quad, scene_of  # noqa: E402
from tracer.simulate import Simulation  # noqa: E402

s, ids = scene_of(quad([-5, -5, 0], [10, 0, 0], [0, 10, 0]))
sim = Simulation(s, {ids[0]: {"type": "lambertian", "reflectance": 0.5}},
                 [{"type": "point", "position": [0, 0, 2], "intensity_cd": 100.0}])
lux = sim.illuminance([[0, 0, 0]], [[0, 0, 1]], max_photons=1000)
t = time.perf_counter()
lum = sim.run({"type": "luminance", "position": [0, 0, 1], "direction": [0, 0, -1]}, max_photons=1000)
print(f"backward lux kernel: {lux.compile_seconds:.2f} s; luminance kernel: {lum.compile_seconds:.2f} s "
      f"(first luminance query {time.perf_counter() - t:.2f} s)")
