"""Compiles the ray kernels of tracer/gpu/traverse.py (closest hit, any hit: the CPU's two-level walk with stacks in
``cuda.local.array``) to sm_90 PTX without a GPU, with the test-only driver stubs of gpu_ptx_sweep.py: run by
tests/tracer/test_gpu_traverse.py in a child; prints one JSON object {kernel: "ok" | error, kernel + "_ptx_bytes": n}.
"""

from __future__ import annotations

import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from gpu_ptx_sweep import CC, stub_driver  # noqa: E402


def main():
    stub_driver()
    import numba
    import numpy as np
    from transport_scenes import box, scene_of

    from tracer.gpu.traverse import any_rays, closest_rays, cuda

    s, _ = scene_of(box([-1, -1, -1], [1, 1, 1]))
    sa = numba.typeof(s.arrays())
    f1, f2, i1 = (numba.typeof(np.zeros(2)), numba.typeof(np.zeros((2, 3))), numba.typeof(np.zeros(2, np.int64)))
    b1 = numba.typeof(np.zeros(2, np.bool_))
    report = {}
    for name, fn, sig in (("closest_rays", closest_rays, (sa, f2, f2, f1, f1, i1, i1, f1, f1, f2)),
                          ("any_rays", any_rays, (sa, f2, f2, f1, b1))):
        try:
            ptx, _ = cuda.compile_ptx(fn, sig, cc=CC)
            report[name] = "ok" if ".entry" in ptx else "no .entry in the PTX"
            report[name + "_ptx_bytes"] = len(ptx)
            report[name + "_local_stack"] = ".local" in ptx
        except Exception as e:   # noqa: BLE001 - reported
            report[name] = f"{type(e).__name__}: {str(e)[:2000]}"
    print(json.dumps(report))


if __name__ == "__main__":
    main()
