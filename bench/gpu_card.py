"""Issue 40's one run on a card: compile, check and measure the GPU path in one call of the device tool.

Every step runs in a child process with its own time limit, inside one overall budget (``--budget``, seconds), and
writes what it found under ``--out`` (the device tool's ``$OUT``) as soon as it ends, so a step that hangs or fails
loses nothing of the others. All children share one numba cache directory, empty at the start: the first step
measures the cold compile, the later ones load what it compiled.

Steps, in order:
1. ``compile``: ``bench.bench_gpu --sections compile`` (first use of the ray kernels and the forward photon kernel in
   a child with an empty cache, then a child that loads them) -> ``gpu-compile.json``.
2. ``traverse``: ``tests/tracer/gpu/gpu_sim_traverse.py`` on the card (not the simulator): the closest-hit and any-hit
   kernels against the CPU walk on random rays, before and after a move, and what each revision uploads.
3. ``transport``: ``tests/tracer/gpu/gpu_sim_transport.py room floor uploads oom lock`` on the card: room answers within
   4 combined sigma of the CPU's, the point source over a floor against E = I cos/r^2, the fallbacks, one job at a
   time.
4. ``kernels``: registers, local memory and the largest block of every kernel compiled on the card.
5. ``bench``: ``bench.bench_gpu --quick --sections rays,commit,photons`` with the packed Mitsuba (OptiX beside us)
   -> ``gpu-bench.json``.
6. ``shapes``: forward photons/s and the backward time to 1 % at 100 floor points for several batch shapes (photons
   per thread, threads per round): how busy the card can be made without changing a kernel.

``card.json`` holds each step's exit code, seconds and output tail, and the checks of steps 2 and 3 judged with a
card's tolerances (a card may contract a*b + c to one rounding, so hits are compared to 1e-6, not bit for bit).
Join the two bench files here with ``python -m bench.bench_gpu --merge gpu-compile.json gpu-bench.json``.

Usage (bench/GPU.md): ``python3 -m bench.gpu_card --out $OUT --mitsuba .mitsuba/mitsuba-cuda.tar.xz``;
``--simulate`` runs the same steps in numba-cuda's simulator on tiny sizes (proves the script, measures nothing).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
TESTS = ROOT / "tests" / "tracer" / "gpu"
Z = 4.0          # combined standard errors allowed between two estimates
HIT_TOL = 1e-6   # hit distance, u, v, normal: a card may round differently from the CPU (FMA)

# A child that reports each compiled kernel's resources on the card (numba-cuda dispatcher methods).
KERNELS_SCRIPT = textwrap.dedent("""
    import json, sys
    sys.path.insert(0, {root!r})
    sys.path.insert(0, {tests!r})
    import numpy as np
    from gpu_sim_transport import POINTS, UP, room_sim
    from tracer.gpu.backend import CudaBackend
    from tracer.gpu import transport, traverse
    sim = room_sim(CudaBackend())
    for est in ("forward", "backward"):
        sim.illuminance(POINTS, UP, radius=0.3, max_photons=2000, estimator=est, seed=1)
    out = {{}}
    for name, k in (("forward_threads", transport.forward_kernel), ("backward_threads", transport.backward_kernel),
                    ("closest_rays", traverse.closest_kernel), ("any_rays", traverse.any_kernel)):
        row = {{"signatures": len(k.overloads)}}
        for what in ("regs_per_thread", "local_mem_per_thread", "shared_mem_per_block", "max_threads_per_block",
                     "const_mem_size"):
            try:
                row[what] = {{str(s): int(v) for s, v in getattr(k, "get_" + what)().items()}}
            except Exception as exc:
                row[what] = f"{{type(exc).__name__}}: {{exc}}"
        out[name] = row
    print(json.dumps(out))
""")

# A child that runs the bench room through CudaBackend cut in several shapes: photons/s (forward) and the time to
# 1 % at 100 floor points (backward), each answer's relative error and where it ran.
SHAPES_SCRIPT = textwrap.dedent("""
    import json, sys, time
    sys.path.insert(0, {root!r})
    import numpy as np
    from bench.bench_gpu import _room
    from bench.bench_transport import floor_points
    from tracer.backends import BatchShape
    from tracer.gpu.backend import CudaBackend
    shapes = {shapes!r}
    target, max_seconds, n = {target!r}, {max_seconds!r}, {n!r}
    pts9, nrm9 = floor_points(3)
    pts, nrm = floor_points(n)
    rows = []
    for fp, bp, first, largest in shapes:
        row = {{"forward_photons": fp, "backward_paths": bp, "first_round": first, "max_round": largest}}
        try:
            sim = _room(CudaBackend(BatchShape(fp, bp, first, largest)))
            sim.illuminance(pts9, nrm9, max_photons=2000, estimator="forward")
            runs = []
            for seed in (1, 2, 3):
                r = sim.illuminance(pts9, nrm9, max_photons={photons!r}, seed=seed, estimator="forward")
                runs.append(r.photons / r.seconds)
            row["forward_photons_per_second"] = float(np.median(runs))
            row["forward_backend"] = r.backend
            sim.illuminance(pts[:2], nrm[:2], max_photons=2000, estimator="backward")
            secs = []
            for seed in (1, 2, 3):
                r = sim.illuminance(pts, nrm, radius=0.05, target_relative_error=target, max_seconds=max_seconds,
                                    seed=seed, estimator="backward")
                secs.append(r.seconds)
            row["backward_to_target_s"] = float(np.median(secs))
            row["backward_photons"] = int(r.photons)
            row["backward_worst_relative_error"] = float(np.max(r.stderr / r.lux))
            row["backward_stop"] = r.stop_reason
            row["backward_backend"] = r.backend
        except Exception as exc:
            row["error"] = f"{{type(exc).__name__}}: {{str(exc)[:400]}}"
        rows.append(row)
        print(json.dumps(row), file=sys.stderr, flush=True)
    print(json.dumps({{"target_relative_error": target, "points": len(pts), "rows": rows}}))
""")

CARD_SHAPES = [(256, 1, 1024, 16384), (64, 1, 4096, 65536), (16, 1, 16384, 262144)]
SIM_SHAPES = [(64, 1, 8, 64)]


def log(msg: str) -> None:
    print(f"gpu_card [{time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def child(cmd: list[str], env: dict, limit: float) -> dict:
    """Run ``cmd``; its exit code, seconds, the JSON of its last stdout line (where it printed one) and a tail of
    its stderr. A child past ``limit`` seconds is killed and says so."""
    t0 = time.perf_counter()
    try:
        r = subprocess.run(cmd, env=env, cwd=ROOT, capture_output=True, text=True, timeout=max(limit, 1.0))
        rc, stdout, stderr = r.returncode, r.stdout, r.stderr
    except subprocess.TimeoutExpired as exc:
        rc = "timeout"
        stdout = exc.stdout.decode() if isinstance(exc.stdout, bytes) else (exc.stdout or "")
        stderr = exc.stderr.decode() if isinstance(exc.stderr, bytes) else (exc.stderr or "")
    out: dict = {"rc": rc, "seconds": round(time.perf_counter() - t0, 2), "stderr_tail": stderr[-3000:]}
    lines = [ln for ln in stdout.strip().splitlines() if ln.startswith("{")]
    if lines:
        try:
            out["result"] = json.loads(lines[-1])
        except json.JSONDecodeError:
            out["stdout_tail"] = stdout[-2000:]
    return out


def judge_traverse(r: dict) -> dict:
    """Hits on the card against the CPU walk (tests/tracer/gpu/test_gpu_traverse.py's checks, a card's tolerance)."""
    checks = {}
    for part in ("before", "after"):
        p = r[part]
        checks[f"{part}_hits_equal"] = bool(p["inst_equal"] and p["prim_equal"] and p["miss_t_inf"]
                                            and p["occluded_equal"])
        checks[f"{part}_within_tol"] = bool(max(p["t_max_abs_diff"], p["uv_max_abs_diff"],
                                                p["normal_max_abs_diff"]) <= HIT_TOL)
    store = {"bvh_f", "bvh_i", "tri_v", "tri_prim", "prim_slot", "tri_n", "geom_node0", "geom_tri0", "geom_ntri",
             "geom_has_normals"}
    checks["move_uploads_top_only"] = bool(r["move_upload"]) and not set(r["move_upload"]) & store
    return checks


def zscore(a: dict, b: dict) -> float:
    la, lb = np.asarray(a["lux"]), np.asarray(b["lux"])
    sd = np.sqrt(np.asarray(a["stderr"]) ** 2 + np.asarray(b["stderr"]) ** 2)
    return float(np.max(np.abs(la - lb) / sd))


def judge_transport(r: dict) -> dict:
    """Room and floor answers (tests/tracer/gpu/test_gpu_transport.py's checks, a card's tolerance)."""
    checks: dict = {}
    for est in ("forward", "backward"):
        room = r["room"][est]
        checks[f"room_{est}_on_card"] = room["cuda"]["backend"].get("name") == "cuda"
        checks[f"room_{est}_max_z_vs_cpu"] = zscore(room["cpu"], room["cuda"])
        checks[f"room_{est}_within_4sigma"] = checks[f"room_{est}_max_z_vs_cpu"] <= Z
        checks[f"room_{est}_same_seed_max_z"] = zscore(room["cuda_seed_of_cpu"], room["cpu_cut_as_cuda"])
        same, cut = np.asarray(room["cuda_seed_of_cpu"]["lux"]), np.asarray(room["cpu_cut_as_cuda"]["lux"])
        checks[f"room_{est}_same_seed_max_rel_diff"] = float(np.max(np.abs(same - cut) / np.abs(cut)))
        floor = r["floor"][est]
        lux, err, exact = np.asarray(floor["lux"]), np.asarray(floor["stderr"]), np.asarray(r["floor"]["exact"])
        checks[f"floor_{est}_on_card"] = floor["backend"].get("name") == "cuda"
        checks[f"floor_{est}_max_z_vs_exact"] = float(np.max(np.abs(lux - exact) / err))
        checks[f"floor_{est}_within_4sigma"] = checks[f"floor_{est}_max_z_vs_exact"] <= Z
    if "uploads" not in r:   # the card run asks for room and floor only (the rest is logic, checked in the simulator)
        return checks
    up = r["uploads"]
    checks["uploads_same_revision_nothing"] = up["same_revision_uploads"] == 0
    checks["uploads_move_top_only"] = len(up["after_move"]) == 1 and set(up["after_move"][0]) == set(up["top_fields"])
    checks["lock_no_overlap"] = r["lock"]["overlaps"] == 0 and not r["lock"]["errors"]
    checks["oom_answers_on_cpu"] = all(r["oom"][e]["answer"]["backend"]["name"] == "in-process"
                                       for e in ("forward", "backward"))
    return checks


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=os.environ.get("OUT"), help="folder for the results (the device tool's $OUT)")
    ap.add_argument("--mitsuba", default=None, help="the packed Mitsuba (bench/GPU.md)")
    ap.add_argument("--budget", type=float, default=420.0, help="seconds for all the steps together")
    ap.add_argument("--steps", default="compile,traverse,transport,bench,kernels,shapes")
    ap.add_argument("--simulate", action="store_true", help="numba-cuda's simulator, tiny sizes: proves the script")
    a = ap.parse_args(argv)
    if not a.out:
        raise SystemExit("gpu_card: say where to write (--out DIR, or $OUT)")
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    steps = a.steps.split(",")
    t_end = time.perf_counter() + a.budget
    cache = tempfile.mkdtemp(prefix="lumenlink-card-numba-")
    env = dict(os.environ, PYTHONPATH=str(ROOT), NUMBA_CACHE_DIR=cache, PYTHONUNBUFFERED="1")
    if a.simulate:
        env["NUMBA_ENABLE_CUDASIM"] = "1"
    py = sys.executable
    report: dict = {"simulate": a.simulate, "budget_s": a.budget, "steps": {}}

    def left(cap: float) -> float:
        return min(cap, t_end - time.perf_counter())

    def save() -> None:
        (out / "card.json").write_text(json.dumps(report, indent=1, default=str))

    try:
        smi = subprocess.run(["nvidia-smi", "--query-gpu=name,driver_version,memory.total,clocks.max.sm",
                              "--format=csv,noheader"], capture_output=True, text=True, timeout=20)
        report["nvidia_smi"] = smi.stdout.strip() or smi.stderr.strip()
    except (OSError, subprocess.TimeoutExpired) as exc:
        report["nvidia_smi"] = f"{type(exc).__name__}: {exc}"
    save()
    bench = [py, "-m", "bench.bench_gpu"] + (["--smoke"] if a.simulate else ["--quick"])
    plan = {
        "compile": (bench + ["--sections", "compile", "--out", str(out / "gpu-compile.json")], 240),
        "traverse": ([py, str(TESTS / "gpu_sim_traverse.py")], 60),
        "transport": ([py, str(TESTS / "gpu_sim_transport.py"), "room", "floor"], 150),
        "kernels": ([py, "-c", KERNELS_SCRIPT.format(root=str(ROOT), tests=str(TESTS))], 40),
        "shapes": ([py, "-c", SHAPES_SCRIPT.format(
            root=str(ROOT), shapes=SIM_SHAPES if a.simulate else CARD_SHAPES, target=0.05 if a.simulate else 0.01,
            max_seconds=5.0 if a.simulate else 8.0, n=3 if a.simulate else 10,
            photons=4000 if a.simulate else 2_000_000)], 100),
        "bench": (bench + ["--sections", "rays,commit,photons", "--out", str(out / "gpu-bench.json")]
                  + (["--mitsuba", a.mitsuba] if a.mitsuba else []), 600),
    }
    for name in steps:
        cmd, cap = plan[name]
        limit = left(cap)
        if limit < 10:
            report["steps"][name] = {"rc": "skipped", "why": "the budget was spent"}
            save()
            continue
        log(f"{name}: up to {limit:.0f} s")
        r = child(cmd, env, limit)
        try:
            if name == "traverse" and "result" in r:
                r["checks"] = judge_traverse(r["result"])
            if name == "transport" and "result" in r:
                r["checks"] = judge_transport(r["result"])
        except (KeyError, TypeError, ValueError) as exc:
            r["checks_error"] = f"{type(exc).__name__}: {exc}"
        report["steps"][name] = r
        log(f"{name}: rc {r['rc']} in {r['seconds']} s" + (f"; checks {r['checks']}" if "checks" in r else ""))
        save()
    report["failed"] = [n for n, r in report["steps"].items() if r["rc"] not in (0, "skipped")
                        or not all(v for k, v in r.get("checks", {}).items() if isinstance(v, bool))]
    save()
    log(f"done; failed: {report['failed'] or 'none'}")
    return 1 if report["failed"] else 0


if __name__ == "__main__":
    sys.exit(main())
