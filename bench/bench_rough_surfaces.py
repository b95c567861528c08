"""The cost of the rough surfaces (issue 38) against the smooth kinds they generalise, and the numba compile time of a
kind's `scatter`. Writes bench/results/rough_surfaces.json.

1. Reflectors: a box room (4 x 4 x 2.5 m, bench_transport's) of `mirror`, `microfacet` (isotropic, brushed metal)
   and `lambertian`, all of reflectance 0.8, under a 1000 cd point light: photons/s of the forward kernel on one
   thread, interleaved rounds, ratios to `mirror`.
2. Glass: 25 cubes (n = 1.5, 10 cm) over a Lambertian floor (bench_polarization_default's glass-heavy scene) of
   a smooth `dielectric` and a rough one (α = 0.2, and brushed 0.05/0.3; the kind `rough_dielectric` until
   2026-12-07): photons/s, ratios to the smooth one, with
   polarization left out (`force_effects_off`) and by default (polarized: both kinds call for it).
3. Compile: in a fresh process with an empty numba cache, the scatter contract's driver (`scatter_contract._run`)
   compiled with each kind's own `scatter` in turn (mirror first, so the shared helpers are compiled before the
   others are timed): seconds per kind (the dielectric's, smooth and rough, is one `scatter`).

Run: ``flock /tmp/ll-cpu.lock .venv/bin/python -m bench.bench_rough_surfaces [--quick]``.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from bench.bench_spectral import _interleaved, _ratios

OUT = Path(__file__).parent / "results" / "rough_surfaces.json"
ROOT = Path(__file__).resolve().parent.parent


def reflectors(rounds: int, photons: int) -> dict:
    from bench.bench_transport import floor_points, room_scene
    from tracer.simulate import Simulation

    s, room = room_scene()
    pts, nrm = floor_points(3)
    lamp = [{"type": "point", "position": [2.0, 2.0, 2.5], "intensity_cd": 1000.0}]
    mats = {"mirror": {"type": "mirror", "reflectance": 0.8},
            "microfacet": {"type": "microfacet", "alpha": 0.3, "reflectance": 0.8},
            "microfacet brushed Al": {"type": "microfacet", "alpha": 0.1, "alpha_y": 0.4, "axis": [1, 0, 0],
                                      "metal": [0.96, 6.69]},
            "lambertian": {"type": "lambertian", "reflectance": 0.8}}
    sims = {n: Simulation(s, {room: m}, lamp) for n, m in mats.items()}
    for sim in sims.values():
        sim.illuminance(pts, nrm, max_photons=2000, estimator="forward")
    times = _interleaved({n: (lambda sim=sim: sim.illuminance(pts, nrm, max_photons=photons, estimator="forward"))
                          for n, sim in sims.items()}, rounds)
    return {"scene": "box room 4 x 4 x 2.5 m of one kind (reflectance 0.8), 1000 cd point light, 9 floor points",
            "photons": photons,
            "photons_per_second": {n: photons / statistics.median(t) for n, t in times.items()},
            "time_ratio_to_mirror": _ratios(times, "mirror")}


def glass(rounds: int, photons: int) -> dict:
    from bench.bench_polarization_default import GLASS_POINTS, glass_cubes

    kinds = {"dielectric": {"type": "dielectric", "ior": 1.5},
             "rough dielectric": {"type": "dielectric", "ior": 1.5, "alpha": 0.2},
             "rough dielectric brushed": {"type": "dielectric", "ior": 1.5, "alpha": 0.05, "alpha_y": 0.3,
                                          "axis": [1, 0, 0]}}
    pts = GLASS_POINTS
    nrm = [[0.0, 0.0, 1.0]] * len(pts)
    q = {"max_photons": photons, "estimator": "forward", "radius": 0.25}
    runs = {}
    for name, body in kinds.items():
        sim = glass_cubes(body)
        for kw in ({}, {"force_effects_off": ["polarization"]}):
            sim.illuminance(pts, nrm, max_photons=2000, estimator="forward", **kw)     # compiled before timing
        runs[f"{name} (polarized)"] = lambda sim=sim: sim.illuminance(pts, nrm, **q)
        runs[f"{name} (unpolarized)"] = lambda sim=sim: sim.illuminance(pts, nrm, force_effects_off=["polarization"],
                                                                        **q)
    times = _interleaved(runs, rounds)
    rates = {n: photons / statistics.median(t) for n, t in times.items()}
    return {"scene": "25 glass cubes (n = 1.5, 10 cm) 0.3 m over a Lambertian floor, 1000 cd point at 1.5 m; the kind "
                     "of the cubes varies", "photons": photons, "photons_per_second": rates,
            "time_ratio_to_dielectric": {
                mode: {n: statistics.median(times[f"{n} ({mode})"]) / statistics.median(times[f"dielectric ({mode})"])
                       for n in kinds} for mode in ("unpolarized", "polarized")}}


COMPILE_SCRIPT = r"""
import json, sys, time
sys.path.insert(0, "tests/tracer/optics")
import numpy as np
from scatter_contract import Case, specs_of
from tracer.optics.surfaces import dielectric, measured_brdf, microfacet, mirror
out = {}
for m in (mirror, dielectric, microfacet, measured_brdf):
    case = Case(m, specs_of(m)[0], "front", 0.0, np.array([0.0, 0.0, -1.0]), ("white", 0.0, 0.0, 0.0, 0.0))
    t0 = time.perf_counter()
    case.run(m.scatter, n=1)
    out[m.NAME] = time.perf_counter() - t0
print(json.dumps(out))
"""


def compile_seconds() -> dict:
    """Seconds to compile the contract's driver with each kind's `scatter`, in a fresh process and numba cache."""
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        r = subprocess.run([sys.executable, "-c", COMPILE_SCRIPT], cwd=ROOT, env=env, capture_output=True, text=True,
                           check=True)
    secs = json.loads(r.stdout.strip().splitlines()[-1])
    return {"seconds": secs, "note": "each: the driver `scatter_contract._run` specialised on the kind's scatter, "
                                     "compiled in order (mirror first pays for the shared helpers)"}


def markdown(result: dict) -> str:
    """The report's section: photons/s and time ratios of each kind against the one it generalises."""
    r, g, c = result["reflectors"], result["glass"], result["compile"]["seconds"]
    out = [f"One thread; `{result['command']}`.", "",
           f"**Reflectors** ({r['scene']}, {r['photons']:,} photons; time per photon against `mirror`, lower is "
           f"cheaper; a rough reflector loses energy to single scattering, so its photons bounce fewer times):", "",
           "| kind | photons/s | time ÷ mirror |", "| --- | ---: | ---: |"]
    out += [f"| {k} | {v:,.0f} | {r['time_ratio_to_mirror'][k]:.2f} |" for k, v in r["photons_per_second"].items()]
    out += ["", f"**Glass** ({g['scene']}, {g['photons']:,} photons; few photons meet the cubes, so the kind's own "
                f"cost is diluted):", "", "| kind | unpolarized: time ÷ dielectric | polarized: time ÷ dielectric |",
            "| --- | ---: | ---: |"]
    un, po = g["time_ratio_to_dielectric"]["unpolarized"], g["time_ratio_to_dielectric"]["polarized"]
    out += [f"| {k} | {un[k]:.2f} | {po[k]:.2f} |" for k in un]
    out += ["", "Compile of each kind's `scatter` (s, fresh cache, in this order: the first pays for the shared "
                "helpers): " + ", ".join(f"{k} {v:.1f}" for k, v in c.items()) + "."]
    return "\n".join(out)


def run(quick: bool = False) -> dict:
    import numba

    numba.set_num_threads(1)
    rounds = 3 if quick else 5
    result = {"reflectors": reflectors(rounds, 100_000 if quick else 500_000),
              "glass": glass(rounds, 50_000 if quick else 200_000),
              "compile": compile_seconds(), "machine_threads": 1,
              "command": "flock /tmp/ll-cpu.lock .venv/bin/python -m bench.bench_rough_surfaces"
                         + (" --quick" if quick else "")}
    result["markdown"] = markdown(result)
    return result


if __name__ == "__main__":
    result = run(quick="--quick" in sys.argv)
    OUT.write_text(json.dumps(result, indent=2, default=float) + "\n")
    print(json.dumps(result, indent=2, default=float))
