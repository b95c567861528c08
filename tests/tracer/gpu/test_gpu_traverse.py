"""Ray queries on a CUDA device (issue 27, tracer/gpu/traverse.py), without a GPU: in numba-cuda's simulator the
closest-hit and any-hit kernels over the uploaded scene give the hits of ``Scene.intersect`` / ``occluded`` on random
rays (t, instance, primitive, u, v, normal to float tolerance); a move uploads only the instances and top levels, a
new geometry the store as well. That both kernels compile to sm_90 PTX is tests/tracer/gpu/test_gpu_ptx.py's.

Each part runs in a child process (the simulator is chosen at numba-cuda's import). Skipped, saying why, where
numba-cuda (or, for PTX, NVVM) is missing.
"""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.tracer.gpu.test_gpu_ptx import ROOT

HERE = Path(__file__).resolve().parent
TOL = 1e-9   # the simulator runs the CPU's compiled walk: equal; a card may contract to FMA


def run_child(script: str, env: dict[str, str], *args: str) -> dict:
    """Run tests/tracer/`script` with `args` in a child process; the JSON object its last line prints."""
    r = subprocess.run([sys.executable, str(HERE / script), *args], env=env, cwd=ROOT, capture_output=True, text=True,
                       timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def simulated():
    if importlib.util.find_spec("numba_cuda") is None:
        pytest.skip("numba-cuda is not installed (pip install -e '.[gpu]')")
    return run_child("gpu_sim_traverse.py", {**os.environ, "NUMBA_ENABLE_CUDASIM": "1", "PYTHONPATH": str(ROOT)})


def test_hits_equal_the_cpu_walk(simulated):
    assert simulated["simulator"] is True
    for part in ("before", "after"):
        r = simulated[part]
        assert r["hits"] > 100 and r["instances_hit"] == [0, 1, 2, 3, 4, 5], r   # all solids, none a sensor
        assert r["inst_equal"] and r["prim_equal"] and r["miss_t_inf"], r
        assert r["t_max_abs_diff"] <= TOL and r["uv_max_abs_diff"] <= TOL and r["normal_max_abs_diff"] <= TOL, r
        assert r["occluded_equal"] and r["occluded"] == r["hits"], r


def test_move_uploads_only_the_top_level(simulated):
    store = {"bvh_f", "bvh_i", "tri_v", "tri_prim", "prim_slot", "tri_n", "geom_node0", "geom_tri0", "geom_ntri",
             "geom_has_normals"}
    assert len(simulated["first_upload"]) == simulated["fields"] == 31   # 21, and 10 of the elements with an inside
    moved = set(simulated["move_upload"])
    assert moved and not moved & store, moved
    assert {"world_from_object", "object_from_world", "top_f", "top_i", "top_items", "top_rec"} <= moved
    assert store <= set(simulated["add_upload"])
