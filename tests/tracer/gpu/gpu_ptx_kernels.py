"""Compiles to sm_90 PTX without a GPU, with the test-only driver stubs of gpu_ptx_sweep.py, the parts named on its
command line, in one process (tests/tracer/gpu/test_gpu_ptx.py runs ``sweep rays batches``): ``sweep``, every device
function of the optics seam (gpu_ptx_sweep.py); ``rays``, the ray kernels of tracer/gpu/traverse.py (closest hit, any
hit: the CPU's two-level walk with stacks in ``cuda.local.array``); ``batches``, the photon batch kernels of
tracer/gpu/transport.py (forward, backward: one thread per batch), with the argument types a real `Simulation`'s
snapshot and query give them. Prints one JSON object {part: {name: "ok" | error, ...}}, each kernel with its
"_ptx_bytes" and "_local_stack", and, where a CUDA toolkit has ptxas, what ptxas for sm_90 made of its PTX, as a
card's driver does before a launch: NVVM's PTX is not always ptxas's (issue 40).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from gpu_ptx_sweep import CC, record_device_functions, stub_driver, sweep_report  # noqa: E402


def batch_kernels():
    """(name, kernel function, argument types) of the photon batch kernels, typed from a real simulation."""
    import numba
    import numpy as np

    from tests.tracer.transport_scenes import box, scene_of
    from tracer.gpu.transport import Tallies, backward_threads, forward_threads
    from tracer.simulate import Simulation
    from tracer.transport.backward import disk_queries
    from tracer.transport.forward import SensorArrays

    s, ids = scene_of(box([-1, -1, -1], [1, 1, 1]))
    sim = Simulation(s, {ids[0]: {"type": "lambertian", "reflectance": 0.5}},
                     [{"type": "point", "position": [0, 0, 0], "intensity_cd": 1.0}])
    sa, M, L = sim.snapshot("white").parts
    i1 = np.zeros(2, np.int64)
    sens = SensorArrays(i1, i1, i1, i1, np.zeros((2, 3)))
    q = disk_queries(np.zeros((2, 3)), np.tile([0.0, 0.0, 1.0], (2, 1)), 0.1)
    out = numba.typeof(Tallies(np.zeros((2, 2)), np.zeros((2, 2), np.int64)))
    t = numba.typeof
    i, f = numba.int64, numba.float64
    return (("forward_threads", forward_threads, (t(sa), t(sa), t(M), t(L), t(sens), i, i, i, i, f, out)),
            ("backward_threads", backward_threads, (t(sa), t(M), t(L), t(q), i, i, i, out)))


def batches_report() -> dict:
    """The photon batch kernels' report."""
    from tracer.gpu.transport import cuda

    report: dict = {}
    for name, fn, sig in batch_kernels():
        compile_one(report, cuda, name, fn, sig)
    return report


def rays_report() -> dict:
    """The ray kernels' report."""
    import numba
    import numpy as np

    from tests.tracer.transport_scenes import box, scene_of
    from tracer.gpu.traverse import any_rays, closest_rays, cuda

    s, _ = scene_of(box([-1, -1, -1], [1, 1, 1]))
    sa = numba.typeof(s.arrays())
    f1, f2, i1 = (numba.typeof(np.zeros(2)), numba.typeof(np.zeros((2, 3))), numba.typeof(np.zeros(2, np.int64)))
    b1 = numba.typeof(np.zeros(2, np.bool_))
    report = {}
    for name, fn, sig in (("closest_rays", closest_rays, (sa, f2, f2, f1, f1, i1, i1, f1, f1, f2)),
                          ("any_rays", any_rays, (sa, f2, f2, f1, b1))):
        compile_one(report, cuda, name, fn, sig)
    return report


def main(parts: list[str]) -> None:
    """The kernels first, recording the device functions each compiles, then the sweep of what no kernel compiled
    (the report's ``in_kernel``: {function: the first kernel that compiled it})."""
    stub_driver()
    make = {"rays": rays_report, "batches": batches_report}
    unknown = [p for p in parts if p not in (*make, "sweep")]
    if unknown or not parts:
        raise SystemExit(f"usage: gpu_ptx_kernels.py PART [PART ...], PART one of {sorted((*make, 'sweep'))}; got "
                         f"{parts}")
    global IN_KERNEL
    IN_KERNEL = record_device_functions()
    out: dict = {part: make[part]() for part in parts if part != "sweep"}
    if "sweep" in parts:
        out["sweep"] = sweep_report(in_kernel=IN_KERNEL)
        out["in_kernel"] = {qual: by for qual, by in IN_KERNEL.items() if by and qual in out["sweep"]}
    print(json.dumps(out))


#: {module.function: the kernel whose PTX compiled it first ("" while that kernel compiles)}, from `main` on
IN_KERNEL: dict[str, str] = {}


def ptxas() -> str | None:
    """CUDA's PTX assembler (``$CUDA_HOME/bin/ptxas`` or on the PATH), or None."""
    home = os.environ.get("CUDA_HOME", "")
    found = os.path.join(home, "bin", "ptxas") if home else ""
    return found if found and os.access(found, os.X_OK) else shutil.which("ptxas")


def assemble(ptx: str) -> dict:
    """The PTX through ptxas for sm_90, as a card's driver does before a launch (NVVM's PTX can still be refused
    there: an LLVM intrinsic left as an external function was, on an H200): {"assembled": "ok" | the error,
    "registers", "stack_bytes", "spill_bytes"} (ptxas -v), or {"assembled": "skipped: ..."} without ptxas."""
    exe = ptxas()
    if exe is None:
        return {"assembled": "skipped: no ptxas (a CUDA toolkit's bin/, or CUDA_HOME)"}
    with tempfile.TemporaryDirectory() as tmp:
        src = os.path.join(tmp, "k.ptx")
        with open(src, "w") as f:
            f.write(ptx)
        r = subprocess.run([exe, f"-arch=sm_{CC[0]}{CC[1]}", "-v", src, "-o", os.path.join(tmp, "k.cubin")],
                           capture_output=True, text=True, timeout=600)
    if r.returncode:
        return {"assembled": (r.stderr or r.stdout)[-2000:]}
    info = r.stderr + r.stdout
    entry = re.findall(r"Used (\d+) registers, used \d+ barriers, (\d+) bytes cumulative stack size", info)
    spills = [int(x) for x in re.findall(r"(\d+) bytes spill stores", info)]
    return {"assembled": "ok", "registers": int(entry[-1][0]) if entry else None,
            "stack_bytes": int(entry[-1][1]) if entry else None, "spill_bytes": max(spills, default=0)}


def compile_one(report, cuda, name, fn, sig):
    """One kernel's entry in `report`; the device functions it compiled are its own in `IN_KERNEL` where its PTX
    has an entry point, left to the sweep where it failed."""
    before = {qual for qual, by in IN_KERNEL.items() if by}
    try:
        ptx, _ = cuda.compile_ptx(fn, sig, cc=CC)
        report[name] = "ok" if ".entry" in ptx else "no .entry in the PTX"
        for qual in IN_KERNEL:
            if qual not in before:
                IN_KERNEL[qual] = name if report[name] == "ok" else ""
        report[name + "_ptx_bytes"] = len(ptx)
        report[name + "_local_stack"] = ".local" in ptx
        for k, v in assemble(ptx).items():
            report[f"{name}_{k}"] = v
    except Exception as e:   # noqa: BLE001 - reported
        report[name] = f"{type(e).__name__}: {str(e)[:2000]}"


if __name__ == "__main__":
    main(sys.argv[1:])
