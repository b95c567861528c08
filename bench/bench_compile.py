"""Where a first session's compile time goes: each kernel's cold compile, by phase and by kind (issue 49).

Each configuration runs `bench/compile_probe.py` in a fresh process with an empty numba cache: commit a room (the
builders), then a forward lux query, a backward one, a luminance meter and a camera, each step's seconds split
into numba's phases (type inference, lowering, LLVM) and into the functions compiled. Configurations, side by side
in one run: the tracer before issue 49 and before the kinds' tables of addresses (the commits of `BEFORE`, each
checked out in a temporary git worktree) and the tracer now; ``python bench/bench_compile.py --o1`` adds the
tracer now at a lower LLVM level (``NUMBA_OPT=1``), whose compile seconds are weighed against the rays and photons
per second that `bench/ab.py` measures (docs/ARCHITECTURE.md, "Compile time").

What a kind adds: the seconds spent compiling the functions of each kind's own module (a surface's ``scatter``, a
light's ``sample`` and ``connect``, a geometry kind's ``intersect``), from the same events. For surfaces and lights
called at their addresses (`tracer.jit.kind_table`) that is what a kind costs; for the rest it is a floor: such a
kind's code is also linked into, optimised and emitted again with every kernel that calls it (the LLVM seconds of
``trace_photons``, ``forward_batches``, the luminance kernels), which these figures count for the caller.

Then, on each configuration's filled cache (a warm install), a second process meets never-met effect sets: the first
lux of a room with rough metal and Mie particles in glass, the first image of one with a mirror and a glass block
(cameras answer Lambertian, specular and Fresnel scenes only): the seconds and what they compiled.

Run: ``lumenlink bench --only compile`` (about 10 minutes on 2 cores; ``--quick``: now only).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PROBE = ROOT / "bench" / "compile_probe.py"
STEPS = ("scene", "forward", "backward", "luminance", "camera")
#: configuration name → the commit it checks out: the last before issue 49's changes to the kernels, the last before
#: surface and light kinds were called through tables of addresses (`tracer.jit.kind_table`)
BEFORE = {"before": "0c32a36", "before kind tables": "e5b73fc"}
#: configuration name → environment; a name of `BEFORE` runs the probe over a worktree of its commit; `--o1` adds the
#: tracer now at LLVM level 1
CONFIGS = {"before": {}, "before kind tables": {}, "now": {}}
O1 = {"now, NUMBA_OPT=1": {"NUMBA_OPT": "1"}}
#: module prefixes whose functions are a kind's own, and the family each names
KIND_FAMILIES = {"tracer.optics.surfaces.": "surface", "tracer.optics.lights.": "light",
                 "tracer.optics.media.": "medium", "tracer.optics.elements.": "element", "tracer.kinds.": "geometry"}
NOT_KINDS = ("dispatch", "base")


WARM_STEPS = ("novel-lux", "novel-image")


def probe(env: dict[str, str], steps=STEPS, then=WARM_STEPS) -> dict:
    """One cold run of the probe in a child with an empty numba cache and `env` added; then, where `then` names
    steps, a second child on the cache the first filled (a warm install) runs them: its result is "warm"."""
    with tempfile.TemporaryDirectory(prefix="lumenlink-compile-") as cache:
        child = {**os.environ, **env, "NUMBA_CACHE_DIR": cache, "PYTHONPATH": str(ROOT)}
        results = []
        for run_steps in (steps, then) if then else (steps,):
            r = subprocess.run([sys.executable, str(PROBE), *run_steps], env=child, capture_output=True, text=True,
                               timeout=1800, cwd=ROOT)
            if r.returncode:
                raise RuntimeError(f"compile probe failed: {r.stderr[-2000:]}")
            results.append(json.loads(r.stdout.strip().splitlines()[-1]))
    out = results[0]
    if then:
        out["warm"] = results[1]
    return out


def compiled(step: dict) -> list[str]:
    """The functions a probe step compiled (module.qualname), sorted."""
    return sorted(set(step["functions"]) - {"(outside)"})


def kind_of(function: str) -> tuple[str, str] | None:
    """(family, kind) of a function in a kind's own module, else None."""
    for prefix, family in KIND_FAMILIES.items():
        if function.startswith(prefix):
            kind = function[len(prefix):].split(".")[0]
            return None if kind in NOT_KINDS else (family, kind)
    return None


def per_kind(result: dict) -> dict[str, float]:
    """Seconds compiling each kind's own functions, over all steps: {"surface microfacet": s, ...}."""
    out: dict[str, float] = defaultdict(float)
    for step in result["steps"].values():
        for function, phases in step["functions"].items():
            k = kind_of(function)
            if k:
                out[" ".join(k)] += sum(phases.values())
    return dict(sorted(out.items(), key=lambda kv: -kv[1]))


def before_checkout(where: Path, name: str) -> Path:
    """A worktree of the commit `BEFORE[name]` under `where` (git worktree add, detached)."""
    path = where / BEFORE[name].replace(" ", "-")
    subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(path), BEFORE[name]], check=True,
                   capture_output=True)
    return path


def label(name: str) -> str:
    return f"{name} (commit {BEFORE[name]})" if name in BEFORE else name


def run(quick: bool = False, o1: bool = False) -> dict:
    configs = {"now": CONFIGS["now"]} if quick else {**CONFIGS, **(O1 if o1 else {})}
    results = {}
    with tempfile.TemporaryDirectory(prefix="lumenlink-before-") as tmp:
        for name, env in configs.items():
            print(f"bench_compile: {name} (fresh process, empty numba cache)", file=sys.stderr, flush=True)
            if name in BEFORE:
                env = {"LUMENLINK_PROBE_ROOT": str(before_checkout(Path(tmp), name))}
            results[name] = probe(env)
        for name in BEFORE:
            if name in configs:
                subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force",
                                str(Path(tmp) / BEFORE[name].replace(" ", "-"))], capture_output=True)
    out = {"configs": {name: {"env": configs[name], "import_seconds": r["import_seconds"],
                              "steps": {s: {"seconds": v["seconds"], "phases": v["phases"]}
                                        for s, v in r["steps"].items()},
                              "kinds": per_kind(r),
                              "warm": {s: {"seconds": v["seconds"], "compiled": compiled(v)}
                                       for s, v in r.get("warm", {}).get("steps", {}).items()},
                              "functions": {s: v["functions"] for s, v in r["steps"].items()}}
                       for name, r in results.items()}}
    out["markdown"] = markdown(out)
    return out


def markdown(out: dict) -> str:
    configs = out["configs"]
    md = ["Cold compile of a first session, each configuration in a fresh process with an empty numba cache "
          "(`bench/compile_probe.py`: commit a room, then a forward lux query, a backward one, a luminance meter "
          "and a 16×12 camera). Seconds per step; in brackets numba's phases, counted exclusively: typing, "
          "lowering (numba IR → LLVM IR, with LLVM work done under a lock numba already held), LLVM (optimisation "
          "and machine code), other passes.", "",
          "| configuration | " + " | ".join(STEPS) + " | total |", "| --- |" + " ---: |" * (len(STEPS) + 1)]
    for name, c in configs.items():
        cells = []
        for s in STEPS:
            v = c["steps"].get(s)
            if v is None:
                cells.append("–")
                continue
            p = v["phases"]
            cells.append(f"{v['seconds']:.1f} ({p.get('typing', 0):.0f} / {p.get('lowering', 0):.0f} / "
                         f"{p.get('llvm', 0):.0f} / {p.get('other', 0):.0f})")
        total = sum(v["seconds"] for v in c["steps"].values())
        md.append(f"| {label(name)} | " + " | ".join(cells) + f" | {total:.1f} |")
    md += ["", "On a warm install (a second process on the cache the first session filled), a room with effects "
           "the first never met: seconds to the first forward lux of a room with rough metal and Mie particles in "
           "glass (spectral light), and to the first 16×12 image of one with a mirror and a glass block, and how many "
           "functions each compiled (issue 49's target: 10 s each).", "",
           "| configuration | first lux, s | compiled | first image, s | compiled |",
           "| --- | ---: | ---: | ---: | ---: |"]
    for name, c in configs.items():
        w = c.get("warm") or {}
        if w:
            md.append(f"| {label(name)} | " + " | ".join(
                f"{w[s]['seconds']:.1f} | {len(w[s]['compiled'])}" if s in w else "– | –" for s in WARM_STEPS) + " |")
    md += ["", "`NUMBA_OPT=1` (LLVM level 1) is not kept: it compiles a cold session in 178 s (2026-11-28, `--o1`), "
           "but its kernels run slower than the issue's 0.95x floor allows (`AB_ENV_B=\"NUMBA_OPT=1 "
           "NUMBA_CACHE_DIR=/tmp/o1\" python bench/ab.py . . room photons:100000 6`, and `mesh incoherent`, "
           "`scene3 camera`: time ratios 1.151, 1.108, 1.057)."]
    first = configs["now"]
    md += ["", "What each kind's own functions cost to compile (s, now). For the surface kinds and thin elements but "
           "the Lambertian one, and the light kinds but the point light, that is all a kind costs: the kernels call "
           "them at their addresses (`tracer.jit.kind_table`). For the others (media, geometry) it is a floor: their "
           "code is optimised and emitted again inside every kernel that calls them, counted for the caller.", "",
           "| kind | seconds |", "| --- | ---: |"]
    md += [f"| {k} | {s:.2f} |" for k, s in first["kinds"].items()]
    for step in ("forward", "luminance"):
        funcs = first["functions"].get(step, {})
        top = sorted(funcs.items(), key=lambda kv: -sum(kv[1].values()))[:8]
        if top:
            md += ["", f"Costliest functions of the {step} step (s, exclusive): " + "; ".join(
                f"`{f.removeprefix('tracer.')}` {sum(p.values()):.1f}" for f, p in top)]
    return "\n".join(md)


if __name__ == "__main__":
    print(json.dumps(run("--quick" in sys.argv, "--o1" in sys.argv), indent=1))
