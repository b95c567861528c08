"""Spectral light: what a wavelength per photon costs, and what each spectral effect costs on the paths that meet it.

1. White scenes pay nothing. The diffuse room of `bench_transport` (2,000,000 photons, one thread) traced by this
   checkout and by the last commit before spectral light (`BASE`, a `git worktree`), in turn, A B B A …
   (`bench/ab.py`, CPU time): the median ratio of neighbouring passes, beside the base against itself (the noise).
2. The spectral state on the same paths. The same room with a 4000 K blackbody source, white against spectral
   (forced; the wavelength is drawn from a random dimension of its own, so the paths are the same) and against
   spectral with the spectrum observed (97 tallies per receiver instead of 1), in turn in one process.
3. Each effect where it acts. A glass block that every photon of a collimated beam enters (500,000 photons):
   clear glass (white), then the same with a Sellmeier index (`dispersion`), a MgF₂ coating (`coating`), and a
   fluorescent inside (`fluorescence`); ratios against clear glass in the spectral state and in white.
4. Compile time: the first answer in a fresh process with an empty numba cache, this checkout on a spectral
   scene against `BASE` on the same scene in white (the kernel is shared, so this is what the new code adds).
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
BASE = "698ac33"   # the last commit before spectral light
BK7 = {"sellmeier": {"b": [1.03961212, 0.231792344, 1.01046945], "c_um2": [0.00600069867, 0.0200179144, 103.560653]}}
MGF2 = {"layers": [{"ior": 1.38, "thickness_nm": 99.64}]}
FLUOR = {"absorption_per_m": {"nm": [400, 480, 500], "values": [200.0, 200.0, 0.0]}, "quantum_yield": 0.9,
         "emission": {"type": "table", "nm": [500, 560, 620], "values": [0.0, 1.0, 0.0]}}


def _interleaved(calls: dict, rounds: int) -> dict[str, list[float]]:
    """CPU seconds of each call (one thread: the batches run on this one), `rounds` times, the order turned each
    round so that neighbours compare like with like."""
    names = list(calls)
    out: dict[str, list[float]] = {n: [] for n in names}
    for r in range(rounds):
        for n in (names if r % 2 == 0 else names[::-1]):
            t0 = time.thread_time()
            calls[n]()
            out[n].append(time.thread_time() - t0)
    return out


def _ratios(times: dict[str, list[float]], ref: str) -> dict[str, float]:
    return {n: statistics.median(t / r for t, r in zip(ts, times[ref], strict=True)) for n, ts in times.items()}


def same_paths(rounds: int) -> dict:
    from bench.bench_transport import floor_points, room_scene
    from tracer.simulate import Simulation

    s, room = room_scene()
    sim = Simulation(s, {room: {"type": "lambertian", "reflectance": 0.5}},
                     [{"type": "point", "position": [2.0, 2.0, 2.5], "intensity_cd": 1000.0,
                       "spectrum": {"type": "blackbody", "kelvin": 4000}}])
    pts, nrm = floor_points(3)
    q = dict(max_photons=2_000_000, estimator="forward")
    for kw in ({}, {"observe": ["spectrum"]}):
        sim.illuminance(pts, nrm, max_photons=1000, estimator="forward", **kw)
    times = _interleaved({"white": lambda: sim.illuminance(pts, nrm, **q),
                          "spectral": lambda: sim.illuminance(pts, nrm, force_effects=["spectral"], **q),
                          "spectral + observe spectrum": lambda: sim.illuminance(pts, nrm, observe=["spectrum"], **q)},
                         rounds)
    return {"seconds": {n: statistics.median(t) for n, t in times.items()}, "ratio_to_white": _ratios(times, "white")}


def effect_costs(rounds: int) -> dict:
    from tracer.scene import Scene
    from tracer.simulate import Simulation
    from tracer.warmup import box

    s = Scene()
    block = s.add_instance(s.add_geometry(*box((-0.05, -0.05, -0.05), (0.05, 0.05, 0.05))), np.eye(4))
    s.commit()
    light = [{"type": "collimated", "origin": [0, 0, 0.2], "direction": [0, 0, -1], "radius": 0.03,
              "illuminance_lx": 1000.0, "spectrum": {"type": "blackbody", "kelvin": 5000}}]
    variants = {"clear glass, white": {}, "clear glass, spectral": {}, "dispersion": {"ior": BK7},
                "coating": {"coating": MGF2},
                "fluorescence": {"medium": {"type": "homogeneous", "fluorescence": FLUOR}}}
    sims = {n: Simulation(s, {block: {"type": "dielectric", "ior": 1.5, **extra}}, light)
            for n, extra in variants.items()}
    pts, nrm = np.array([[0.0, 0.0, -0.1]]), np.array([[0.0, 0.0, 1.0]])
    forced = {"clear glass, spectral": ["spectral"]}
    q = dict(max_photons=500_000, estimator="forward", radius=0.05)
    for n, sim in sims.items():
        sim.illuminance(pts, nrm, max_photons=1000, estimator="forward", force_effects=forced.get(n, ()))
    calls = {n: (lambda sim=sim, n=n: sim.illuminance(pts, nrm, force_effects=forced.get(n, ()), **q))
             for n, sim in sims.items()}
    times = _interleaved(calls, rounds)
    photons = q["max_photons"]
    return {"photons_per_second": {n: photons / statistics.median(t) for n, t in times.items()},
            "ratio_to_clear_spectral": _ratios(times, "clear glass, spectral"),
            "ratio_to_clear_white": _ratios(times, "clear glass, white"),
            "effects": {n: sim.effects for n, sim in sims.items()}}


def _worktree(base: str = BASE) -> Path:
    """A checkout of commit `base` under the temporary directory (made once), sharing this checkout's .venv."""
    path = Path(tempfile.gettempdir()) / f"lumenlink-{base}"
    if not (path / "bench" / "ab.py").exists():
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "-f", str(path), base], check=True,
                       capture_output=True)
    venv = path / ".venv"
    if not venv.exists():
        venv.symlink_to(ROOT / ".venv")
    return path


def white_pays_nothing(pairs_n: int, base_commit: str = BASE) -> dict:
    """The diffuse room A/B against `base_commit` (`bench/ab.py`), beside the base against itself (the noise)."""
    from bench.ab import pairs

    base = _worktree(base_commit)
    a, b = pairs(str(base), str(ROOT), "room", "photons:2000000", pairs_n)
    aa, ab = pairs(str(base), str(base), "room", "photons:2000000", pairs_n)   # the noise: the base against itself
    noise = [y / x for x, y in zip(aa, ab, strict=True)]
    ratio = [tb / ta for ta, tb in zip(a, b, strict=True)]
    return {"base": base_commit, "base_seconds": statistics.median(a), "this_seconds": statistics.median(b),
            "ratio_median": statistics.median(ratio), "ratio_range": [min(ratio), max(ratio)], "pairs": pairs_n,
            "base_against_itself_median": statistics.median(noise),
            "base_against_itself_range": [min(noise), max(noise)]}


FIRST_ANSWER = """
import time, numpy as np
t0 = time.perf_counter()
from tracer.scene import Scene
from tracer.simulate import Simulation
from tracer.warmup import box
s = Scene()
i = s.add_instance(s.add_geometry(*box((-0.05, -0.05, -0.05), (0.05, 0.05, 0.05))), np.eye(4))
s.commit()
glass = {{"type": "dielectric", "ior": {ior}}}
light = [{{"type": "point", "position": [0, 0, 0.2], "flux_lm": 100.0}}]
Simulation(s, {{i: glass}}, light).illuminance([[0, 0, -0.1]], [[0, 0, 1]], max_photons=1000, estimator="forward")
print(time.perf_counter() - t0)
"""


def compile_seconds() -> dict:
    out = {}
    for name, checkout, ior in (("base (white)", _worktree(), "1.5"), ("this (spectral)", ROOT, repr(BK7))):
        with tempfile.TemporaryDirectory() as cache:
            env = dict(os.environ, NUMBA_CACHE_DIR=cache, LUMENLINK_WARM_KERNELS="0")
            r = subprocess.run([sys.executable, "-c", FIRST_ANSWER.format(ior=ior)], cwd=checkout, env=env,
                               capture_output=True, text=True, check=True)
            out[name] = float(r.stdout.strip().splitlines()[-1])
    out["ratio"] = out["this (spectral)"] / out["base (white)"]
    return out


def run(quick: bool = False) -> dict:
    import numba

    numba.set_num_threads(1)
    rounds = 3 if quick else 7
    result = {"same_paths": same_paths(rounds), "effects": effect_costs(rounds)}
    if not quick:
        result["white_pays_nothing"] = white_pays_nothing(12)
        result["compile"] = compile_seconds()
    sp, ef = result["same_paths"], result["effects"]
    lines = ["Medians of CPU seconds on one thread; ratios are of neighbouring passes (this machine).", "",
             "| diffuse room, 2M photons | s | × white |", "| --- | --- | --- |"]
    lines += [f"| {n} | {sp['seconds'][n]:.3f} | {sp['ratio_to_white'][n]:.3f} |" for n in sp["seconds"]]
    lines += ["", "| glass block, every photon enters, 500k photons | photons/s | × clear spectral | × clear white |",
              "| --- | --- | --- | --- |"]
    lines += [f"| {n} | {ef['photons_per_second'][n]:,.0f} | {ef['ratio_to_clear_spectral'][n]:.3f} | "
              f"{ef['ratio_to_clear_white'][n]:.3f} |" for n in ef["photons_per_second"]]
    if "white_pays_nothing" in result:
        w = result["white_pays_nothing"]
        lines += ["", f"White diffuse room (2M photons), this checkout against {w['base']} (before spectral light), "
                      f"{w['pairs']} A/B pairs: {w['this_seconds']:.3f} s against {w['base_seconds']:.3f} s, ratio "
                      f"{w['ratio_median']:.3f} (range {w['ratio_range'][0]:.3f}–{w['ratio_range'][1]:.3f}); the "
                      f"base against itself, the same way: {w['base_against_itself_median']:.3f} (range "
                      f"{w['base_against_itself_range'][0]:.3f}–{w['base_against_itself_range'][1]:.3f})."]
        c = result["compile"]
        lines += ["", f"First answer, empty numba cache, no background compilation: this checkout on a dispersive "
                      f"glass block {c['this (spectral)']:.1f} s, {BASE} on the same block in white "
                      f"{c['base (white)']:.1f} s (ratio {c['ratio']:.2f})."]
    result["markdown"] = "\n".join(lines)
    return result


if __name__ == "__main__":
    import json

    print(json.dumps(run(quick="--quick" in sys.argv), indent=2, default=float))
