"""bench/bench_gpu.py without a GPU: ``--smoke`` runs every section end to end on tiny sizes in numba-cuda's
simulator and writes a JSON of the shape a GPU run writes (keys and types checked here, figures meaningless); where
no GPU is found, or only the simulator, the benchmark says so, exits 2 and writes no results file.

Each run is a child process (the simulator is chosen at numba-cuda's import). Skipped, saying why, where numba-cuda
is missing.
"""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "bench" / "results" / "gpu.json"
STORE = {"bvh_f", "bvh_i", "tri_v", "tri_prim", "prim_slot", "tri_n", "geom_node0", "geom_tri0", "geom_ntri",
         "geom_has_normals"}

pytestmark = pytest.mark.skipif(importlib.util.find_spec("numba_cuda") is None,
                                reason="numba-cuda is not installed (pip install -e '.[gpu]')")


def _env(**extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_ENABLE_CUDASIM", "LUMENLINK_MITSUBA")}
    return {**env, "PYTHONPATH": str(ROOT), **extra}


def _results_state():
    return RESULTS.stat().st_mtime_ns if RESULTS.exists() else None


@pytest.mark.slow   # ~20 s where numba's cache holds the tracer's kernels; ~200 s on 2 cores where it is empty
def test_smoke_runs_every_section_in_the_simulator(tmp_path):
    out = tmp_path / "gpu.json"
    before = _results_state()
    r = subprocess.run([sys.executable, "-m", "bench.bench_gpu", "--smoke", "--out", str(out)], cwd=ROOT,
                       env=_env(), capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    assert _results_state() == before, "a smoke run must not touch bench/results/gpu.json"
    d = json.loads(out.read_text())
    assert d["device"] == "cuda:0 simulator" and d["smoke"] is True
    assert isinstance(d["markdown"], str) and "### Closest hit" in d["markdown"]

    rows = d["rows"]
    assert len(rows) == 8   # two scenes × incoherent, camera × two ray counts
    assert {(w["scene_key"], w["rays"]) for w in rows} == {(s, k) for s in ("scene3", "mesh")
                                                          for k in ("incoherent", "camera")}
    for w in rows:
        assert isinstance(w["scene"], str) and isinstance(w["rays"], str)
        assert isinstance(w["n_rays"], int) and w["n_rays"] > 0
        assert isinstance(w["gpu_mrays"], float) and w["gpu_mrays"] > 0
        assert isinstance(w["cpu_mrays"], float) and w["cpu_mrays"] > 0
        assert isinstance(w["cpu_threads"], int) and w["cpu_threads"] >= 1
        assert w["optix_mrays"] is None   # no packed Mitsuba given: the column is skipped, with the reason
        assert w["gpu_cpu_same_hit"] == 1.0, w   # the simulator runs the CPU's own walk
    assert "no packed Mitsuba" in d["optix"]["skipped"]

    c = d["commit"]
    assert c["blas_built"] == 0 and c["uploaded_fields"] and not STORE & set(c["uploaded_fields"]), c
    assert isinstance(c["commit_and_upload_s"], float)

    p = d["photons"]
    assert p["cpu"]["rate"]["photons_per_second"] > 0
    assert p["cpu"]["to_target"]["backward"]["stop_reason"] in ("target_relative_error", "max_seconds")
    if p["gpu_skipped"] is None:   # CudaBackend is there: its rows, and answers within error bars of the CPU's
        assert p["gpu"]["rate"]["photons_per_second"] > 0
        for est in ("backward", "forward"):
            x = p["gpu"]["to_target"][est]
            assert "skipped" in x or x["max_abs_z_vs_cpu"] <= 4.0, x
    else:
        assert isinstance(p["gpu_skipped"], str) and "gpu" not in p

    comp = d["compile"]
    for label in ("first", "second"):
        assert "error" not in comp[label], comp[label]
        assert comp[label]["closest_kernel_s"] >= 0 and comp[label]["any_kernel_s"] >= 0


@pytest.mark.parametrize("how", ["script", "bench.run"])
@pytest.mark.parametrize("where", ["no device", "simulator only"])
def test_without_a_gpu_it_says_so_and_writes_nothing(how, where):
    env = _env(CUDA_VISIBLE_DEVICES="") if where == "no device" else _env(NUMBA_ENABLE_CUDASIM="1")
    cmd = ([sys.executable, "-m", "bench.bench_gpu"] if how == "script"
           else [sys.executable, "-c", "import sys; from bench import run; sys.exit(run.main(['gpu']))"])
    before = _results_state()
    r = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 2, (r.returncode, r.stderr[-2000:])
    assert "no results file was written" in r.stderr and "never writes estimated figures" in r.stderr
    assert ("simulator" in r.stderr) == (where == "simulator only"), r.stderr
    assert _results_state() == before
