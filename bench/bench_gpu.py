"""The tracer on a CUDA GPU (issue 27) beside Mitsuba 3 / OptiX on the same card and our CPU on all its cores.

Sections
--------
1. Closest hit, Mrays/s: the paper's scene 3 (20,968 objects, 302,822 triangles, two levels) and the 1M-triangle
   bumpy sphere, incoherent and camera rays (the rays of ``bench/instructions.py``), 1M and 16M rays. Ours on the GPU
   (:class:`tracer.gpu.traverse.DeviceScene`'s closest-hit kernel over rays already on the card: the kernel launch
   timed to a device synchronisation, warm, median of the repeats; also end to end through
   ``DeviceScene.intersect``, host arrays in and out); Mitsuba 3 ``cuda_ad_rgb`` (OptiX's own traversal) on the same
   card and the same rays (``ray_intersect`` on the flattened scene; imported from the packed wheels of
   ``shared/tools/pack-mitsuba-cuda``, ``--mitsuba PATH`` or ``LUMENLINK_MITSUBA``; the column is skipped, with the
   reason, where it is absent); our CPU on all its cores (``Scene.intersect``, ``cpu_threads``).
2. Photons: forward photons/s in the diffuse room of ``bench/bench_transport.py`` and the time to 1 % at 100 floor
   points, through ``tracer.simulate.Simulation(..., backend=CudaBackend())`` where ``tracer.gpu.backend`` has it
   (rows skipped with the reason where not), beside the CPU on all its cores.
3. Commit after moving one object of scene 3, the upload of the new revision included (``DeviceScene.update``
   sends only the instances and top levels on a move).
4. First-use compile seconds of the GPU kernels, in a child process with an empty numba cache in a temporary
   directory, then in a second child with that cache kept.

One command on a machine with a GPU (bench/GPU.md): ``python3 -m bench.bench_gpu --mitsuba PACK`` writes
``bench/results/gpu.json`` and the REPORT.md section. Where numba-cuda finds no GPU, or only its simulator, it says so
and exits 2 without writing a results file: no figure here is ever estimated. ``--smoke`` runs every section on tiny
sizes in numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``) and writes to a temporary path: it proves the code
paths, its figures mean nothing (tests/bench/test_bench_gpu.py runs it).

What each section measures, and the sizes it runs at, is in ``bench/gpu_sections.py``; here the device, the
run, the results file, the report and the command line.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:   # `python3 bench/bench_gpu.py` on a machine where lumenlink is not installed
    sys.path.insert(0, str(ROOT))

from bench.gpu_sections import (  # noqa: E402 - after the sys.path line above
    FULL,
    MITSUBA_ENV,
    MITSUBA_VARIANT,
    QUICK,
    SMOKE,
    Mitsuba,
    Sizes,
    _room,  # noqa: F401 - bench/gpu_card.py imports it from here
    build_cases,
    commit_after_move,
    compile_section,
    cpu_threads,
    log,
    photons_section,
    ray_rows,
)

SECTIONS = ("compile", "rays", "commit", "photons")
#: what ``bench/bench_transport.py`` measured on 2 CPU cores for the time to 1 % at 100 floor points (backward)
TRANSPORT_CPU_2_CORES_S = 3.2
#: issue 27's targets (benchmark, not timed tests)
TARGETS = {"scene3_incoherent_mrays": 100.0, "scene3_camera_mrays": 300.0, "time_to_1pct_s": 0.2,
           "compile_s": 10.0, "commit_s": 1e-3}


class NoGPU(SystemExit):
    """No GPU to measure on: the message says why; nothing is written."""

    def __init__(self, why: str):
        super().__init__(f"bench_gpu: {why}. Nothing was measured and no results file was written "
                         "(this benchmark never writes estimated figures); run it on a machine with a CUDA GPU "
                         "(bench/GPU.md).")
        self.code = 2


_CACHE: tempfile.TemporaryDirectory | None = None


def share_cache_with_children() -> str | None:
    """Point this process's numba cache at a new, empty temporary directory before numba is imported (where it is
    not yet), so that the compile section's first child finds it empty and this process then loads what the
    children compiled instead of compiling it again (minutes of a 10-minute device call). The directory, or None."""
    global _CACHE
    if "numba" in sys.modules:
        return None
    chosen = os.environ.get("NUMBA_CACHE_DIR")
    if chosen and (not Path(chosen).exists() or not any(Path(chosen).iterdir())):
        return chosen   # a caller's own empty cache (bench/gpu_card.py shares one across its steps): keep it
    if _CACHE is None:
        _CACHE = tempfile.TemporaryDirectory(prefix="lumenlink-numba-")
        os.environ["NUMBA_CACHE_DIR"] = _CACHE.name
    return _CACHE.name


# ---------------------------------------------------------------- the device
def find_gpu(smoke: bool) -> str:
    """The device's name ("cuda:0 NVIDIA H100 80GB HBM3"); :class:`NoGPU` where there is none to measure on. In
    ``smoke`` the simulator is required instead."""
    from tracer.gpu.device import find_cuda

    name, why = find_cuda()
    if smoke:
        if name != "cuda:0 simulator":
            raise SystemExit(f"bench_gpu --smoke: numba-cuda's simulator did not start ({name or why})")
        return name
    if name is None:
        raise NoGPU(f"no GPU found: {why}")
    if name.endswith("simulator"):
        raise NoGPU("numba-cuda runs only its simulator here (NUMBA_ENABLE_CUDASIM=1), which is no GPU")
    return name


def device_info(name: str) -> dict:
    import numba

    from tracer.gpu import cuda as _cuda

    cuda = _cuda()
    info = {"name": name, "numba": numba.__version__, "numpy": np.__version__}
    try:
        from importlib.metadata import version

        info["numba_cuda"] = version("numba-cuda")
    except Exception:   # noqa: BLE001 - a version we cannot read is only left out
        pass
    if not name.endswith("simulator"):
        try:   # descriptive only: a field numba-cuda cannot read is left out, the run goes on
            dev = cuda.get_current_device()
            info["compute_capability"] = ".".join(map(str, dev.compute_capability))
            info["multiprocessors"] = int(dev.MULTIPROCESSOR_COUNT)
            info["memory_gib"] = round(cuda.current_context().get_memory_info()[1] / 2**30, 1)
            info["driver"] = ".".join(map(str, cuda.cudadrv.driver.driver.get_version()))
        except Exception as exc:   # noqa: BLE001
            info["unread"] = f"{type(exc).__name__}: {exc}"
    return info


# ---------------------------------------------------------------- run
def measure(sizes: Sizes, device: str, mitsuba: str | None, sections=SECTIONS, variant: str = MITSUBA_VARIANT,
            cache_dir: str | None = None) -> dict:
    """Every section asked for, on the device found; the result dict (with its ``markdown``)."""
    out: dict = {"device": device, "device_info": device_info(device), "cpu_threads": cpu_threads(),
                 "sections": list(sections), "sizes": sizes.__dict__, "targets": TARGETS}
    if "compile" in sections:   # first: a child compiling alone
        out["compile"] = compile_section(sizes, cache_dir)
    cases = None
    if "rays" in sections or "commit" in sections:
        log("building scene 3 and the bumpy sphere")
        cases = build_cases(sizes)
    if "rays" in sections:
        peer = Mitsuba(mitsuba, variant)
        out["rows"], out["builds"] = ray_rows(cases, sizes, peer)
        out["optix"] = {"variant": variant, "version": peer.version, "skipped": peer.skipped}
    if "commit" in sections:
        log("commit after a move")
        out["commit"] = commit_after_move(cases[0], sizes)
    if "photons" in sections:
        out["photons"] = photons_section(sizes)
    out["markdown"] = markdown(out)
    return out


def run(quick: bool = False) -> dict:
    """`bench.run`'s entry (``lumenlink bench --only gpu``): :class:`NoGPU` (exit 2, nothing written) without a GPU;
    the packed Mitsuba from ``LUMENLINK_MITSUBA``."""
    cache = share_cache_with_children()
    try:
        device = find_gpu(smoke=False)
    except NoGPU as exc:
        print(exc.args[0], file=sys.stderr)
        raise
    return measure(QUICK if quick else FULL, device, os.environ.get(MITSUBA_ENV), cache_dir=cache)


# ---------------------------------------------------------------- report
def _f(x, nd: int = 1) -> str:
    """A figure with ``nd`` decimals and thousands commas; "—" where it was not measured."""
    if x is None:
        return "—"
    return f"{x:,.{nd}f}"


def markdown(r: dict) -> str:
    """The REPORT.md section of a results dict: the device and targets, then a part for each section it holds."""
    md = _device_and_targets(r)
    for key, part in (("rows", _closest_hit), ("commit", _commit), ("photons", _photons), ("card", _card_steps),
                      ("compile", _first_use)):
        if key in r:
            md += part(r)
    return "\n".join(md)


def _device_and_targets(r: dict) -> list[str]:
    """The opening paragraph: the device, the CPU threads beside it, and issue 27's targets."""
    return [f"Device: **{r['device']}**; CPU columns on all {r['cpu_threads']} threads of its host. Issue 27's "
            "targets: scene 3 incoherent ≥ 100 Mrays/s, camera ≥ 300 (parity with OptiX the goal); time to 1 % at "
            "100 floor points ≤ 0.2 s warm; first-use compile ≤ 10 s; commit after a move ≤ 1 ms with the upload.", ""]


def _closest_hit(r: dict) -> list[str]:
    """The closest-hit table, Mrays/s, one row per scene × rays × count; then hit agreement and why OptiX is
    missing where it is."""
    o = r["optix"]
    md = [f"### Closest hit (Mrays/s, median of {r['sizes']['repeats']} rounds, warm)", "",
          "Each round times ours on the GPU, the two Mitsuba calls and ours on the CPU one after the other on the "
          "same rays; a ratio (as speeds) is the median of the rounds' ratios.", "",
          "*GPU*: our closest-hit kernel (`tracer.gpu.traverse`, the CPU's own walk compiled by numba-cuda) over "
          "rays already on the card, launch to device sync; *end to end*: `DeviceScene.intersect` with host "
          f"arrays in and out. *OptiX*: Mitsuba 3 `{o['variant']}` ({o['version'] or 'not loaded'}) on the same "
          "card and rays, `ray_intersect` (t, primitive, uv, normal evaluated) on the flattened scene; "
          "*prelim.*: `ray_intersect_preliminary`. *CPU*: `Scene.intersect` on all threads. *Same hit*: the "
          "fraction of rays whose instance and primitive the GPU and the CPU agree on.", "",
          "| scene | rays | GPU | end to end | OptiX | prelim. | GPU / OptiX | CPU | threads | GPU / CPU | "
          "hit fraction | same hit |",
          "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for w in r["rows"]:
        md.append(f"| {w['scene']} | {w['rays']} ({w['n_rays']:,}) | {_f(w['gpu_mrays'])} | "
                  f"{_f(w['gpu_end_to_end_mrays'])} | {_f(w['optix_mrays'])} | "
                  f"{_f(w['optix_preliminary_mrays'])} | {_f(w['gpu_over_optix'], 2)} | "
                  f"{_f(w['cpu_mrays'], 2)} | {w['cpu_threads']} | {_f(w['gpu_over_cpu'], 1)} | "
                  f"{w['hit_fraction']:.4f} | {w['gpu_cpu_same_hit']:.6f} |")
    agree = [w["optix_cpu_hit_agreement"] for w in r["rows"] if "optix_cpu_hit_agreement" in w]
    if agree:
        md += ["", f"Mitsuba and ours hit or miss alike for at least {min(agree):.6f} of the rays in every row; "
                   f"GPU and CPU hit the same primitive for at least "
                   f"{min(w['gpu_cpu_same_hit'] for w in r['rows']):.6f}."]
    if o["skipped"]:
        md += ["", f"OptiX columns not measured: {o['skipped']}."]
    return md


def _commit(r: dict) -> list[str]:
    """Commit and upload after one move, in ms."""
    c = r["commit"]
    return ["", f"### Commit after moving one object of {c['objects']:,} (median of {c['moves']})", "",
            f"Commit {c['commit_s'] * 1e3:.3f} ms + upload of the new revision {c['upload_s'] * 1e3:.3f} ms = "
            f"**{c['commit_and_upload_s'] * 1e3:.3f} ms** (worst {c['max_commit_and_upload_s'] * 1e3:.3f} ms); "
            f"uploaded {c['uploaded_bytes']:,} bytes in {len(c['uploaded_fields'])} fields "
            f"({', '.join(c['uploaded_fields'])}); bottom levels rebuilt: {c['blas_built']}."]


def _to_target_cell(tt: dict, estimator: str) -> str:
    """One time-to-target cell: seconds, why the run stopped, its worst relative error; "—" where not run."""
    x = tt.get(estimator, {})
    if "seconds" not in x:
        return "—"
    return (f"{x['seconds']:.3f} s ({x['stop_reason']}, worst {x['worst_relative_error']:.4f}, "
            f"{x['runs']} run{'s' if x['runs'] > 1 else ''})")


def _photons(r: dict) -> list[str]:
    """The photons table (photons/s, seconds to the target error) for the GPU and the CPU; then the 2-core CPU
    figure, why the GPU rows are missing where they are, and how far the GPU's answers are from the CPU's (in σ)."""
    p = r["photons"]
    md = ["", "### Photons in the diffuse room (bench/bench_transport.py)", "",
          f"| where | ran on (the answer's backend) | forward photons/s | time to {r['sizes']['target']:.0%} at "
          f"{r['sizes']['room_points'] ** 2} floor points, backward | forward |",
          "| --- | --- | ---: | ---: | ---: |"]
    for key, label in (("gpu", f"GPU ({r['device']})"), ("cpu", f"CPU, {p['cpu_threads']} threads")):
        if key not in p:
            md.append(f"| {label} | — | — | — | — |")
            continue
        b = p[key]["rate"].get("backend") or {}
        ran = b.get("device") or f"{b.get('name', '?')}, {b.get('threads', '?')} threads"
        if b.get("fallback"):   # CudaBackend handed the query to the CPU (a scene that does not fit)
            ran += f" ({b['fallback']})"
        tt = p[key]["to_target"]
        md.append(f"| {label} | {ran} | {p[key]['rate']['photons_per_second']:,.0f} | "
                  f"{_to_target_cell(tt, 'backward')} | {_to_target_cell(tt, 'forward')} |")
    md.append("")
    md.append(f"On 2 CPU cores bench_transport measured {TRANSPORT_CPU_2_CORES_S} s to 1 % (backward).")
    if p.get("gpu_skipped"):
        md.append(f"GPU rows not measured: {p['gpu_skipped']}.")
    if "gpu" in p:
        zs = {e: x["max_abs_z_vs_cpu"] for e, x in p["gpu"]["to_target"].items() if "max_abs_z_vs_cpu" in x}
        if zs:
            md.append("GPU against CPU answers, largest |ΔE| / σ combined over the points: " + ", ".join(
                f"{e} {z:.2f}" for e, z in zs.items()) + " (agreement: ≤ 4).")
    return md


def _card_steps(r: dict) -> list[str]:
    """bench/gpu_card.py's steps: exit status, seconds, and their checks."""
    md = ["", f"### The card run's steps (bench/gpu_card.py, one call of {r['card']['budget_s']:.0f} s)", "",
          "| step | exit | seconds | checks (the simulator tests' checks, a card's tolerances) |",
          "| --- | --- | ---: | --- |"]
    for name, st in r["card"]["steps"].items():
        checks = st.get("checks") or {}
        shown = ", ".join(f"{k} {v:.2f}" if isinstance(v, float) else f"{k} {'yes' if v else 'NO'}"
                          for k, v in checks.items()) or st.get("why", "—")
        md.append(f"| {name} | {st['rc']} | {st.get('seconds', '—')} | {shown} |")
    return md


def _first_use(r: dict) -> list[str]:
    """The compile section's two child processes: seconds to first use of each kernel, or why it failed."""
    c = r["compile"]
    md = ["", "### First use of the GPU kernels (child processes)", ""]
    for label, what in (("first", "empty numba cache" if c["cold_cache"] else "default numba cache"),
                        ("second", "the cache the first left")):
        x = c.get(label, {})
        if "error" in x:
            md.append(f"- {label} process ({what}): failed: `{x['error'][-300:]}`")
            continue
        photons = (f", forward photon kernel {x['forward_photons_first_use_s']:.2f} s"
                   if "forward_photons_first_use_s" in x else f"; photons: {x.get('photons_skipped', '—')}")
        md.append(f"- {label} process ({what}): closest-hit kernel {x['closest_kernel_s']:.2f} s, any-hit "
                  f"{x['any_kernel_s']:.2f} s{photons} (CPU kernels before them {x['cpu_first_use_s']:.2f} s, "
                  f"import {x['import_s']:.2f} s)")
    return md


# ---------------------------------------------------------------- command line
def write_results(res: dict, path: Path | None) -> Path:
    """``res`` to ``path`` (default bench/results/gpu.json, then REPORT.md rebuilt), stamped as `bench.run` does."""
    from bench import run as bench_run

    res.update(date=res.get("date") or time.strftime("%Y-%m-%d %H:%M:%S"),
               machine=res.get("machine") or bench_run.machine())
    target = path or bench_run.RESULTS / "gpu.json"
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(json.dumps(res, indent=2, default=float))
    if path is None:
        log(f"report {bench_run.write_report()}")
    return target


def merge(files: list[str]) -> dict:
    """Results of split runs (``--sections``) on one device joined, later files over earlier ones."""
    parts = [json.loads(Path(f).read_text()) for f in files]
    cards = [p for p in parts if "steps" in p]   # bench/gpu_card.py's card.json: its checks, beside the figures
    parts = [p for p in parts if "steps" not in p]
    devices = {p.get("device") for p in parts}
    if len(devices) != 1 or any(p.get("smoke") for p in parts):
        raise SystemExit(f"bench_gpu --merge: the files come from different devices or smoke runs: {sorted(devices)}")
    res: dict = {}
    for p in parts:
        res.update({k: v for k, v in p.items() if k != "sections"})
    res["sections"] = [s for s in SECTIONS if any(s in p.get("sections", []) for p in parts)]
    for card in cards:
        res["card"] = {"nvidia_smi": card.get("nvidia_smi"), "budget_s": card.get("budget_s"),
                       "steps": {n: {k: v for k, v in st.items() if k in ("rc", "seconds", "checks", "why")}
                                 for n, st in card["steps"].items()}}
        res["machine"] = f"device host of {card.get('nvidia_smi')} ({res.get('cpu_threads')} CPU threads)"
    res["markdown"] = markdown(res)
    return res


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python3 -m bench.bench_gpu", description=__doc__.split("\n\n")[0])
    ap.add_argument("--mitsuba", default=os.environ.get(MITSUBA_ENV),
                    help=f"packed Mitsuba 3 (the .tar.xz of shared/tools/pack-mitsuba-cuda, or the directory it was "
                         f"unpacked into); default ${MITSUBA_ENV}; without it the OptiX column is skipped")
    ap.add_argument("--mitsuba-variant", default=MITSUBA_VARIANT, help=argparse.SUPPRESS)   # llvm_ad_rgb: a CPU check
    ap.add_argument("--quick", action="store_true", help="1M rays only, fewer moves, shorter budgets")
    ap.add_argument("--sections", default=",".join(SECTIONS),
                    help=f"comma-separated subset of {','.join(SECTIONS)} (to split a run across device calls; "
                         "join the parts with --merge)")
    ap.add_argument("--out", help="write the JSON here instead of bench/results/gpu.json (--smoke: a temporary file "
                                  "by default)")
    ap.add_argument("--merge", nargs="+", metavar="JSON",
                    help="join the JSON files of split runs into bench/results/gpu.json and REPORT.md (no GPU needed)")
    ap.add_argument("--smoke", action="store_true",
                    help="tiny sizes in numba-cuda's simulator, written to --out or a temporary file: proves the code "
                         "paths; its figures mean nothing")
    args = ap.parse_args(argv)
    if args.merge:
        path = write_results(merge(args.merge), Path(args.out) if args.out else None)
        log(f"merged into {path}")
        return 0
    sections = tuple(s for s in args.sections.split(",") if s)
    bad = set(sections) - set(SECTIONS)
    if bad:
        ap.error(f"unknown sections {sorted(bad)}; known: {', '.join(SECTIONS)}")
    if args.smoke:
        os.environ["NUMBA_ENABLE_CUDASIM"] = "1"   # before numba is imported: nothing above imports it
        device = find_gpu(smoke=True)
        res = measure(SMOKE, device, args.mitsuba, sections, args.mitsuba_variant)
        res.update(smoke=True)
        out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="lumenlink-bench-gpu-")) / "gpu.json"
        write_results(res, out)
        print(res["markdown"])
        log(f"smoke run (simulator, figures meaningless) written to {out}")
        return 0
    cache = share_cache_with_children()
    try:
        device = find_gpu(smoke=False)
    except NoGPU as exc:
        print(exc.args[0], file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    res = measure(QUICK if args.quick else FULL, device, args.mitsuba, sections, args.mitsuba_variant, cache)
    res.update(quick=args.quick, wall_seconds=time.perf_counter() - t0)
    path = write_results(res, Path(args.out) if args.out else None)
    print(res["markdown"])
    log(f"written {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
