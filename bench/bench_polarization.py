"""Polarized light and particle media: what a Stokes vector per photon costs, and Mie against Henyey–Greenstein.

1. Unpolarized scenes pay nothing. The diffuse room of `bench_transport` (2,000,000 photons, one thread) traced by
   this checkout and by the last commit before polarization (`BASE`, a `git worktree`), in turn (`bench/ab.py`,
   CPU time): the median ratio of neighbouring passes, beside the base against itself (the noise).
2. Polarized against unpolarized on the same scenes, in turn in one process: the diffuse room (forced
   `polarization`: the same paths, every diffuse bounce depolarizes), the same with Stokes observed, and a glass
   block every photon of a collimated beam enters (Fresnel with Mueller matrices; the reflect/refract choice then
   depends on each photon's state, so the paths are alike but not the same).
3. A particle medium: a slab of polystyrene spheres (Mie, τ ≈ 1.8 at 550 nm) against a Henyey–Greenstein slab with
   the same σa, σs and g, both spectral; and the Mie slab polarized (azimuth by rejection, scattering matrix).
4. Compile time: the first answer in a fresh process with an empty numba cache, this checkout on a polarized
   glass block with Stokes observed against `BASE` on the same block unpolarized (one kernel is shared, so this is
   what the new code adds).
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile

import numpy as np

from bench.bench_spectral import ROOT, _interleaved, _ratios, _worktree, white_pays_nothing

BASE = "3efe31d"   # the last commit before polarization
PARTICLES = {"radius_um": 0.5, "ior": [1.59, 0.0], "number_per_m3": 1e13}


def same_scenes(rounds: int) -> dict:
    from bench.bench_transport import floor_points, room_scene
    from tracer.scene import Scene
    from tracer.simulate import Simulation
    from tracer.warmup import box

    s, room = room_scene()
    room_sim = Simulation(s, {room: {"type": "lambertian", "reflectance": 0.5}},
                          [{"type": "point", "position": [2.0, 2.0, 2.5], "intensity_cd": 1000.0}])
    pts, nrm = floor_points(3)
    g = Scene()
    block = g.add_instance(g.add_geometry(*box((-0.05, -0.05, -0.05), (0.05, 0.05, 0.05))), np.eye(4))
    g.commit()
    glass_sim = Simulation(g, {block: {"type": "dielectric", "ior": 1.5}},
                           [{"type": "collimated", "origin": [0.02, 0, 0.2], "direction": [0.3, 0.1, -1],
                             "radius": 0.02, "illuminance_lx": 1000.0}])
    gp, gn = np.array([[0.0, 0.0, -0.1]]), np.array([[0.0, 0.0, 1.0]])
    room_q = dict(max_photons=2_000_000, estimator="forward")
    glass_q = dict(max_photons=500_000, estimator="forward", radius=0.05)
    for sim, p, n in ((room_sim, pts, nrm), (glass_sim, gp, gn)):
        for kw in ({}, {"observe": ["stokes"]}):
            sim.illuminance(p, n, max_photons=1000, estimator="forward", **kw)
    room_t = _interleaved({
        "unpolarized": lambda: room_sim.illuminance(pts, nrm, **room_q),
        "polarized": lambda: room_sim.illuminance(pts, nrm, force_effects=["polarization"], **room_q),
        "polarized + observe stokes": lambda: room_sim.illuminance(pts, nrm, observe=["stokes"], **room_q)}, rounds)
    glass_t = _interleaved({
        "unpolarized": lambda: glass_sim.illuminance(gp, gn, **glass_q),
        "polarized": lambda: glass_sim.illuminance(gp, gn, force_effects=["polarization"], **glass_q),
        "polarized + observe stokes": lambda: glass_sim.illuminance(gp, gn, observe=["stokes"], **glass_q)}, rounds)
    return {"room_seconds": {n: statistics.median(t) for n, t in room_t.items()},
            "room_ratio": _ratios(room_t, "unpolarized"),
            "glass_photons_per_second": {n: glass_q["max_photons"] / statistics.median(t) for n, t in glass_t.items()},
            "glass_ratio": _ratios(glass_t, "unpolarized")}


def mie_against_hg(rounds: int) -> dict:
    from tracer.optics.mie import Particles, mie_table
    from tracer.scene import Scene
    from tracer.simulate import Simulation
    from tracer.warmup import box

    s = Scene()
    slab = s.add_instance(s.add_geometry(*box([-5, -5, -0.1], [5, 5, 0])), np.eye(4))
    s.commit()
    t = mie_table(Particles(PARTICLES["radius_um"], *PARTICLES["ior"], PARTICLES["number_per_m3"]), np.ones(471))
    i550 = 550 - 360
    hg = {"type": "dielectric", "ior": 1.0, "medium": {
        "type": "homogeneous", "scattering_per_m": float(t.sigma_sca[i550]), "g": float(t.g[i550]),
        "absorption_per_m": float(t.sigma_ext[i550] - t.sigma_sca[i550])}}
    light = [{"type": "collimated", "origin": [0, 0, 1], "direction": [0, 0, -1], "radius": 0.01,
              "illuminance_lx": 100.0, "spectrum": {"type": "monochromatic", "nm": 550}}]
    sims = {"Henyey–Greenstein (same σ, g), spectral": Simulation(s, {slab: hg}, light),
            "Mie": Simulation(s, {slab: {"type": "dielectric", "ior": 1.0,
                                              "medium": {"type": "homogeneous", "particles": PARTICLES}}}, light)}
    pts, nrm = np.array([[0.0, 0.0, -0.11]]), np.array([[0.0, 0.0, 1.0]])
    q = dict(max_photons=300_000, estimator="forward", radius=0.5)
    forced = {"Henyey–Greenstein (same σ, g), spectral": ["spectral"]}
    for n, sim in sims.items():
        sim.illuminance(pts, nrm, max_photons=1000, estimator="forward", force_effects=forced.get(n, ()))
        sim.illuminance(pts, nrm, max_photons=1000, estimator="forward", observe=["stokes"])
    calls = {n: (lambda sim=sim, n=n: sim.illuminance(pts, nrm, force_effects=forced.get(n, ()), **q))
             for n, sim in sims.items()}
    calls["Mie, polarized"] = lambda: sims["Mie"].illuminance(pts, nrm, observe=["stokes"], **q)
    times = _interleaved(calls, rounds)
    return {"tau": float(t.sigma_ext[i550] * 0.1), "g": float(t.g[i550]),
            "photons_per_second": {n: q["max_photons"] / statistics.median(ts) for n, ts in times.items()},
            "ratio_to_hg": _ratios(times, "Henyey–Greenstein (same σ, g), spectral")}


FIRST_ANSWER = """
import time, numpy as np
t0 = time.perf_counter()
from tracer.scene import Scene
from tracer.simulate import Simulation
from tracer.warmup import box
s = Scene()
i = s.add_instance(s.add_geometry(*box((-0.05, -0.05, -0.05), (0.05, 0.05, 0.05))), np.eye(4))
s.commit()
light = [{{"type": "point", "position": [0, 0, 0.2], "flux_lm": 100.0}}]
Simulation(s, {{i: {{"type": "dielectric", "ior": 1.5}}}}, light).illuminance([[0, 0, -0.1]], [[0, 0, 1]],
    max_photons=1000, estimator="forward"{observe})
print(time.perf_counter() - t0)
"""


def compile_seconds() -> dict:
    out = {}
    for name, checkout, observe in (("base (unpolarized)", _worktree(BASE), ""),
                                    ("this (polarized)", ROOT, ", observe=['stokes']")):
        with tempfile.TemporaryDirectory() as cache:
            env = dict(os.environ, NUMBA_CACHE_DIR=cache, LUMENLINK_WARM_KERNELS="0")
            r = subprocess.run([sys.executable, "-c", FIRST_ANSWER.format(observe=observe)], cwd=checkout, env=env,
                               capture_output=True, text=True, check=True)
            out[name] = float(r.stdout.strip().splitlines()[-1])
    out["ratio"] = out["this (polarized)"] / out["base (unpolarized)"]
    return out


def run(quick: bool = False) -> dict:
    import numba

    numba.set_num_threads(1)
    rounds = 3 if quick else 7
    result = {"same_scenes": same_scenes(rounds), "mie": mie_against_hg(rounds)}
    if not quick:
        result["unpolarized_pays_nothing"] = white_pays_nothing(12, BASE)
        result["compile"] = compile_seconds()
    sc, mie = result["same_scenes"], result["mie"]
    lines = ["Medians of CPU seconds on one thread; ratios are of neighbouring passes (this machine).", "",
             "| diffuse room, 2M photons (same paths) | s | × unpolarized |", "| --- | --- | --- |"]
    lines += [f"| {n} | {sc['room_seconds'][n]:.3f} | {sc['room_ratio'][n]:.3f} |" for n in sc["room_seconds"]]
    lines += ["", "| glass block, every photon enters, 500k photons | photons/s | × unpolarized |",
              "| --- | --- | --- |"]
    lines += [f"| {n} | {sc['glass_photons_per_second'][n]:,.0f} | {sc['glass_ratio'][n]:.3f} |"
              for n in sc["glass_photons_per_second"]]
    lines += ["", f"| particle slab, τ = {mie['tau']:.2f}, g = {mie['g']:.3f}, 300k photons | photons/s | × HG |",
              "| --- | --- | --- |"]
    lines += [f"| {n} | {mie['photons_per_second'][n]:,.0f} | {mie['ratio_to_hg'][n]:.3f} |"
              for n in mie["photons_per_second"]]
    if "unpolarized_pays_nothing" in result:
        w = result["unpolarized_pays_nothing"]
        lines += ["", f"Unpolarized diffuse room (2M photons), this checkout against {w['base']} (before "
                      f"polarization), {w['pairs']} A/B pairs: {w['this_seconds']:.3f} s against "
                      f"{w['base_seconds']:.3f} s, ratio "
                      f"{w['ratio_median']:.3f} (range {w['ratio_range'][0]:.3f}–{w['ratio_range'][1]:.3f}); the "
                      f"base against itself, the same way: {w['base_against_itself_median']:.3f} (range "
                      f"{w['base_against_itself_range'][0]:.3f}–{w['base_against_itself_range'][1]:.3f})."]
        c = result["compile"]
        lines += ["", f"First answer, empty numba cache, no background compilation: this checkout on a glass block "
                      f"with Stokes observed {c['this (polarized)']:.1f} s, {BASE} on the same block unpolarized "
                      f"{c['base (unpolarized)']:.1f} s (ratio {c['ratio']:.2f})."]
    result["markdown"] = "\n".join(lines)
    return result


if __name__ == "__main__":
    import json

    print(json.dumps(run(quick="--quick" in sys.argv), indent=2, default=float))
