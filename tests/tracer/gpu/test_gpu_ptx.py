"""One source for both targets (issue 27): every device function of the optics seam, the rng, frames, spectra,
polarization, thin films and the sensors' crossings and tallies compiles to PTX for sm_90 with numba-cuda, from the
same plain Python the CPU's ``njit`` compiles; so do the ray kernels of tracer/gpu/traverse.py (closest and any hit,
stacks in local memory) and the photon batch kernels of tracer/gpu/transport.py (forward, backward: one thread per
batch), and ptxas for sm_90 assembles each kernel's PTX as a card's driver does (issue 40), where a CUDA toolkit has
it. No GPU needed.

All of it compiles in one child (tests/tracer/gpu/gpu_ptx_kernels.py ``sweep rays batches``, started by
`tests.ptx_child`), once for the module: the kernels first, then the sweep compiles alone only the device functions
no kernel compiled (a function a kernel's PTX holds, with the types the kernel gives it, is "ok" there; the report's
``in_kernel`` names the kernel): 184 s against 214 s when the sweep compiled every function alone first (issue 49).
Under ``make test`` the controller starts that child at the session's start at the lowest CPU priority and this
module reads its report. Skipped, with the reason, where numba-cuda (``pip install -e '.[gpu]'``; the dev extra has
it) or NVVM (a CUDA toolkit, ``CUDA_HOME``) is missing.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests import ptx_child

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="module")
def ptx_report() -> dict:
    """{"sweep": {function: "ok" | error}, "rays": {...}, "batches": {...}}: one child compiles all three."""
    try:
        returncode, stdout, stderr = ptx_child.run()
    except RuntimeError as why:
        pytest.skip(str(why))
    assert returncode == "0", (returncode, stderr[-3000:])
    return json.loads(stdout.strip().splitlines()[-1])


def kernels_compiled_and_assembled(report: dict, names: tuple[str, ...]) -> None:
    """Each kernel compiled to PTX with an entry point and its stacks in local memory, and ptxas took it."""
    for name in names:
        assert report[name] == "ok", report[name]
        assert report[name + "_local_stack"], report
        assembled = report[name + "_assembled"]   # ptxas takes the PTX as a card's driver does (issue 40: it refused
        assert assembled == "ok" or assembled.startswith("skipped"), (name, assembled)  # llvm.prefetch on an H200)


def test_ray_kernels_compile_to_ptx(ptx_report):
    kernels_compiled_and_assembled(ptx_report["rays"], ("closest_rays", "any_rays"))


def test_batch_kernels_compile_to_ptx(ptx_report):
    kernels_compiled_and_assembled(ptx_report["batches"], ("forward_threads", "backward_threads"))


def test_physics_compiles_to_ptx(ptx_report):
    report = ptx_report["sweep"]
    failed = {k: v for k, v in report.items() if v != "ok"}
    assert not failed, json.dumps(failed, indent=1)
    families = {k.rsplit(".", 1)[0] for k in report}
    # every family of the seam was swept, down to each kind
    for mod in ("surfaces.lambertian", "surfaces.dielectric", "surfaces.mix", "surfaces.mirror", "surfaces.dispatch",
                "elements.diffuser", "elements.polarizer", "elements.retarder", "media.homogeneous",
                "media.fluorescence", "media.dispatch", "lights.point", "lights.spot", "lights.collimated",
                "lights.area", "lights.goniometric", "lights.dispatch", "tracer.rng", "frames", "spectra",
                "polarization", "thinfilm", "disk_sensor", "rect_sensor"):
        assert any(f.endswith(mod) for f in families), mod
    for fn in ("surfaces.dispatch.scatter", "surfaces.dispatch.albedo", "media.dispatch.medium_event",
               "lights.dispatch.sample_emission", "lights.dispatch.light_connect", "forward.record_stokes",
               "forward.record_spectrum", "rng.uniform", "rng.path_key"):
        assert any(k.endswith(fn) for k in report), fn
    assert len(report) >= 90, len(report)
    # most of the seam reaches the card inside the photon kernels; what they compiled is theirs, not re-swept
    assert ptx_report["in_kernel"]["tracer.optics.surfaces.dispatch.scatter"] in ("forward_threads", "backward_threads")
