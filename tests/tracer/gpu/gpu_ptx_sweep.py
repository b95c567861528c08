"""Compiles the device functions of the optics seam (and the rng, frames, spectra, polarization, thin films, the
sensors' crossings and tallies) to PTX for sm_90 with numba-cuda, without a GPU or a driver: `sweep_report`, run by
gpu_ptx_kernels.py ``sweep`` in tests/tracer/gpu/test_gpu_ptx.py's child; alone, it prints one JSON object
{name: "ok" | error}.

Each function goes in as numba-cuda's ``cuda.jit(device=True)`` would take it: its plain Python (``.py_func``)
with argument types of the values the CPU kernels pass (the tuples from a real ``Simulation``'s snapshot, the
scalars by their names). Two lookups that need a driver are stubbed for the test only (:func:`stub_driver`):
the current device's compute capability, which numba-cuda asks when it compiles a callee that is a CPU ``@njit``
dispatcher for CUDA, and NVRTC's list of architectures (``NUMBA_FORCE_CUDA_CC`` answers it). NVVM and libdevice
must be present (``CUDA_HOME``, a CUDA toolkit or the ``cuda-toolkit[nvvm]`` wheels).

Usage: python tests/tracer/gpu/gpu_ptx_sweep.py [name-substring ...]
"""

from __future__ import annotations

import importlib
import inspect
import json
import os
import sys
import time

os.environ.setdefault("NUMBA_FORCE_CUDA_CC", "9.0")
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

CC = (9, 0)

#: modules whose device functions are swept, in the order of the report
MODULES = [
    "tracer.rng", "tracer.optics.frames", "tracer.optics.spectra", "tracer.optics.polarization",
    "tracer.optics.thinfilm", "tracer.optics.coating", "tracer.optics.mie",
    "tracer.optics.surfaces.base", "tracer.optics.surfaces.black", "tracer.optics.surfaces.lambertian",
    "tracer.optics.surfaces.mirror", "tracer.optics.surfaces.dielectric", "tracer.optics.surfaces.mix",
    "tracer.optics.surfaces.measured_brdf", "tracer.optics.surfaces.dispatch",
    "tracer.optics.elements.base", "tracer.optics.elements.diffuser", "tracer.optics.elements.polarizer",
    "tracer.optics.elements.retarder",
    "tracer.optics.media.homogeneous", "tracer.optics.media.fluorescence", "tracer.optics.media.dispatch",
    "tracer.optics.lights.base", "tracer.optics.lights.point", "tracer.optics.lights.spot",
    "tracer.optics.lights.collimated", "tracer.optics.lights.area", "tracer.optics.lights.goniometric",
    "tracer.optics.lights.dispatch",
    "tracer.kinds.disk_sensor", "tracer.kinds.rect_sensor", "tracer.accel.spawn",
    "tracer.transport.forward",
]

#: host-side helpers (they allocate arrays or run whole batches): not device functions, not swept
HOST = {
    "tracer.rng._uniforms", "tracer.optics.mie.amplitude_sums", "tracer.transport.forward.trace_photons",
    "tracer.transport.forward.forward_batches",
}


def stub_driver():
    """Test-only stand-ins for the two lookups numba-cuda makes of a driver or NVRTC when it compiles to PTX."""
    from tracer.gpu import cuda

    cuda()
    import numba.cuda.cuda_paths as cuda_paths
    import numba.cuda.dispatcher as dispatcher

    class _Device:
        compute_capability = CC
        name = "PTX only (no device)"

    dispatcher.get_current_device = lambda: _Device()
    cuda_paths._get_nvrtc_path = lambda: ("stub", None)   # NVRTC is not needed to emit PTX


def values():
    """Argument values of a small scene as the CPU kernels receive them, by argument name."""
    import numpy as np

    from tests.tracer.transport_scenes import quad, scene_of
    from tracer.simulate import Simulation

    s, ids = scene_of(quad([0, 0, 0], [1, 0, 0], [0, 1, 0]))
    sim = Simulation(s, {ids[0]: {"type": "lambertian", "reflectance": 0.5}},
                     [{"type": "point", "position": [0.5, 0.5, 1.0], "intensity_cd": 100.0}])
    sa, M, L = sim.snapshot("polarized-spectral").parts
    f, i, u = 0.5, np.int64(1), np.uint64(7)
    farr, iarr = np.zeros(8), np.zeros(8, np.int64)
    v = {
        "sa": sa, "M": M, "L": L,
        "pol": farr, "med": iarr, "stack": iarr, "tstack": farr, "cdf": farr, "table": farr, "layers": np.zeros((4, 4)),
        "tab": np.zeros((4, 4)), "rows": np.zeros((2, 4)), "p": farr, "bi": np.zeros(8, np.int32),
        "bf": np.zeros(8, np.float32), "tri": np.zeros(9, np.float32), "grid": farr, "tally": farr, "far": farr,
        "ref": np.zeros((2, 3)),
        "out_inst": iarr, "out_t": farr, "out_u": farr, "out_v": farr, "out_cos": farr, "c_inst": iarr,
        "key": u, "z": u, "seed": i, "batch": i, "path": i,
        "any_hit": True, "reverse": False, "from_outside": True,
    }
    for name in ("inst", "prim", "depth", "dim", "j", "mi", "col", "lo", "n", "first", "count", "row0", "slot", "g",
                 "sp", "base", "r", "b", "tri0", "at", "si", "n_bins", "ra", "rb", "level"):
        v[name] = i
    return v, f


OVERRIDES = {
    # (module.function): {argument: value kind} where the name alone misleads
    "tracer.optics.spectra.sample_grid": {"f": "farr"},
    "tracer.optics.polarization.apply_interface": {"b": "f"},
    "tracer.optics.polarization.interface_power": {"b": "f"},
    "tracer.optics.polarization.leave_plane": {"b": "f"},
    "tracer.optics.thinfilm._times": {"b": "f"},
    "tracer.optics.thinfilm._s_amplitudes": {"b": "f"},
    "tracer.optics.thinfilm._p_amplitudes": {"b": "f"},
    "tracer.optics.thinfilm._abs2": {"z": "c"},
    "tracer.optics.lights.base.in_light_frame": {"b": "f"},
    "tracer.transport.forward.record_spectrum": {"b": "i"},
}


def arg_types(qual, fn, v, f):
    import numba
    import numpy as np

    over = OVERRIDES.get(qual, {})
    out = []
    for name in inspect.signature(fn.py_func).parameters:
        k = over.get(name)
        if k == "f":
            val = f
        elif k == "farr":
            val = np.zeros(8)
        elif k == "i":
            val = np.int64(1)
        elif k == "c":
            val = 1.0 + 0.5j
        else:
            val = v.get(name, f)
        out.append(numba.typeof(val))
    return tuple(out)


def device_functions(mods, only):
    from numba.core.registry import CPUDispatcher

    for modname in mods:
        mod = importlib.import_module(modname)
        for name, obj in vars(mod).items():
            if not isinstance(obj, CPUDispatcher) or obj.py_func.__module__ != modname:
                continue
            qual = f"{modname}.{name}"
            if qual in HOST or (only and not any(s in qual for s in only)):
                continue
            yield qual, obj


def record_device_functions() -> dict[str, str]:
    """{module.function: ""} of every device function numba-cuda compiles from here on, as the callee of a kernel
    (its ``compile_device``); the caller names the kernel in the values (`in_kernel`)."""
    import numba.cuda.dispatcher as dispatcher

    compiled: dict[str, str] = {}
    compile_device = dispatcher.CUDADispatcher.compile_device

    def recording(self, args, return_type=None):
        f = self.py_func
        compiled.setdefault(f"{f.__module__}.{f.__qualname__}", "")
        return compile_device(self, args, return_type)

    dispatcher.CUDADispatcher.compile_device = recording
    return compiled


def sweep_report(only=(), in_kernel=None) -> dict:
    """{module.function: "ok" | the error} for every device function of `MODULES` (those naming a substring of
    `only`, where given); each one's seconds go to standard error. `in_kernel`: {module.function: kernel} of those a
    kernel already compiled to PTX with the argument types it gives them (`record_device_functions`): "ok" without
    compiling them again alone (with made-up types), which was most of the sweep's minute (issue 49)."""
    from tracer.gpu import cuda

    numba_cuda = cuda()
    v, f = values()
    report = {}
    in_kernel = in_kernel or {}
    for qual, fn in device_functions(MODULES, only):
        t = time.perf_counter()
        if in_kernel.get(qual):
            report[qual] = "ok"
            continue
        try:
            sig = arg_types(qual, fn, v, f)
            numba_cuda.compile_ptx(fn.py_func, sig, device=True, cc=CC)
            report[qual] = "ok"
        except Exception as e:   # noqa: BLE001 - the report names each failure
            msg = str(e).strip().splitlines()
            report[qual] = f"{type(e).__name__}: " + " | ".join(line.strip() for line in msg[:6] if line.strip())
        print(f"{qual}: {report[qual][:200]} ({time.perf_counter() - t:.1f} s)", file=sys.stderr)
    return report


if __name__ == "__main__":
    stub_driver()
    print(json.dumps(sweep_report(sys.argv[1:])))
