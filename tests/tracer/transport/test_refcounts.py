"""Per-ray kernels are compiled without numba's reference counting (docs/CONTRACTS.md).

A jitted function that takes the scene tuple (or the light, material, sensor or query tuples) and is
called once per ray or bounce paid, with reference counting on, an increment and a decrement for
every array of the tuple on each call: as long as the traversal itself (transport ran 2.3x faster
without). Only the entry kernels, which allocate and run once per batch, may keep it.
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil

from numba.core.registry import CPUDispatcher

import tracer
from tracer.jit import TUPLES

#: entry points that allocate (their stacks, their outputs): called once per batch, or for convenience
ALLOCATING = {"tracer.transport.backward.backward_batches", "tracer.accel.lanes.batch",
              "tracer.transport.radiance.radiance_batches",
             "tracer.transport.forward.forward_batches",
              "tracer.accel.traverse.intersect_closest", "tracer.accel.traverse.intersect_any",
              "tracer.accel.traverse.sensor_crossings", "tracer.accel.traverse.closest_each",
              "tracer.accel.lanes._trace_block"}   # its lanes' state, once per block of rays


def _kernels_taking_tuples() -> dict[str, CPUDispatcher]:
    found = {}
    for info in pkgutil.walk_packages(tracer.__path__, "tracer."):
        mod = importlib.import_module(info.name)
        for name, obj in vars(mod).items():
            if isinstance(obj, CPUDispatcher) and obj.__module__ == mod.__name__:
                params = list(inspect.signature(obj.py_func).parameters)
                if params and params[0] in TUPLES:
                    found[f"{mod.__name__}.{name}"] = obj
    return found


def test_per_ray_kernels_count_no_references() -> None:
    kernels = _kernels_taking_tuples()
    assert {"tracer.accel.traverse.closest_with_stacks", "tracer.transport.forward.trace_photons",
            "tracer.optics.lights.spot.sample",
            "tracer.optics.surfaces.dielectric.scatter"} <= set(kernels)   # the walk finds them
    assert ALLOCATING <= set(kernels)
    counting = sorted(n for n, k in kernels.items() if k.targetoptions.get("_nrt", True) and n not in ALLOCATING)
    assert counting == [], f"compile these with _nrt=False (docs/CONTRACTS.md): {counting}"
