"""Polarization by physics (issue 38): what the new default costs where it turns on, and that a diffuse room pays
nothing new. Writes bench/results/polarization_default.json.

1. A diffuse room (bench_transport's): the effect set stays ``["lambertian"]``, so the kernel and the photons are
   those of before; the one new cost is deciding (`tracer.effects.explain_effects`), timed here.
2. A glass-heavy scene: 5 x 5 glass cubes (n = 1.5, 10 cm) over a Lambertian floor (rho 0.5) under a 1000 cd point
   light; the floor's illuminance on 5 disks of 0.25 m, forward, the default (polarized) against
   `force_effects_off`, in turn on one thread (CPU seconds, `bench.bench_spectral._interleaved`), and the answer's
   `physics_left_out` (what leaving polarization out moves, with its error).
3. The demo car (lumenlink.demo's model, materials, lights and floor grid, through the service): photons per second
   of the grid's simulation, default against `force_effects_off` (the service's own `seconds - compile_seconds`).
4. The cost of a `microfacet` bounce against `mirror` and `lambertian` (`microfacet_cost`).

Run: ``flock /tmp/ll-cpu.lock .venv/bin/python -m bench.bench_polarization_default [--quick]``.
"""

from __future__ import annotations

import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.bench_spectral import _interleaved, _ratios

OUT = Path(__file__).parent / "results" / "polarization_default.json"


def diffuse_room() -> dict:
    from bench.bench_transport import room_scene
    from tracer.effects import explain_effects
    from tracer.simulate import Simulation

    s, room = room_scene()
    lam = {"type": "lambertian", "reflectance": 0.5}
    lamp = [{"type": "point", "position": [2.0, 2.0, 2.5], "intensity_cd": 1000.0}]
    sim = Simulation(s, {room: lam}, lamp)
    n = 2000
    t0 = time.perf_counter()
    for _ in range(n):
        explain_effects([lam], lamp)
    return {"effects": sim.effects, "polarization": sim.effect_reasons["polarization"],
            "explain_microseconds": 1e6 * (time.perf_counter() - t0) / n}


GLASS_POINTS = [[0.0, 0.0, 0.0], [0.3, 0.0, 0.0], [0.45, 0.45, 0.0], [0.15, -0.6, 0.0], [-0.9, 0.2, 0.0]]


def glass_cubes(body: dict):
    """The glass-heavy scene: 25 cubes (10 cm, material `body`) on a 0.3 m lattice 0.3 m over a Lambertian floor
    (ρ 0.5), a 1000 cd point light at 1.5 m; its `Simulation` (floor points: `GLASS_POINTS`)."""
    from tracer.scene import Scene
    from tracer.simulate import Simulation
    from tracer.warmup import box

    s = Scene()
    floor = s.add_instance(s.add_geometry(*box([-3, -3, -0.1], [3, 3, 0.0])), np.eye(4))
    cube = s.add_geometry(*box([-0.05, -0.05, 0.0], [0.05, 0.05, 0.1]))
    mats = {floor: {"type": "lambertian", "reflectance": 0.5}}
    for i in range(5):
        for j in range(5):
            t = np.eye(4)
            t[:3, 3] = [0.3 * (i - 2), 0.3 * (j - 2), 0.3]
            mats[s.add_instance(cube, t)] = body
    s.commit()
    return Simulation(s, mats, [{"type": "point", "position": [0.1, 0.05, 1.5], "intensity_cd": 1000.0}])


def glass_heavy(rounds: int, photons: int) -> dict:
    sim = glass_cubes({"type": "dielectric", "ior": 1.5})
    pts = GLASS_POINTS
    nrm = [[0.0, 0.0, 1.0]] * len(pts)
    q = {"max_photons": photons, "estimator": "forward", "radius": 0.25}
    for kw in ({}, {"force_effects_off": ["polarization"]}):
        sim.illuminance(pts, nrm, max_photons=2000, estimator="forward", **kw)     # compiled before timing
    times = _interleaved({"default (polarized)": lambda: sim.illuminance(pts, nrm, **q),
                          "force_effects_off": lambda: sim.illuminance(pts, nrm, force_effects_off=["polarization"],
                                                                       **q)}, rounds)
    res = sim.illuminance(pts, nrm, force_effects_off=["polarization"], physics_left_out=["polarization"], seed=1, **q)
    e = res.physics_left_out["polarization"]
    return {"scene": "25 glass cubes (n = 1.5, 10 cm) 0.3 m over a Lambertian floor, 1000 cd point at 1.5 m",
            "effects": sim.effects, "photons": photons,
            "photons_per_second": {n: photons / statistics.median(t) for n, t in times.items()},
            "ratio": _ratios(times, "force_effects_off"),
            "lux_unpolarized": res.lux.tolist(), "stderr": res.stderr.tolist(),
            "polarization_difference": e["difference"].tolist(), "difference_stderr": e["stderr"].tolist()}


def demo_car(rounds: int, photons: int) -> dict:
    import httpx

    import cad_adapter
    from cad_adapter.client import Pusher
    from cad_adapter.samples import car_assembly
    from lumenlink import demo
    from lumenlink.demo_car import GRID, dress

    with tempfile.TemporaryDirectory() as tmp:
        doc = cad_adapter.read_document(car_assembly(), sidecar=Path(tmp) / "ids.json")
        tess = cad_adapter.tessellate(doc)
        uuid_of = {node.name: node.uuid for node in doc.nodes}
        with demo.running_service(Path(tmp) / "var") as base, httpx.Client(base_url=base, timeout=600.0) as http:
            with Pusher(base) as pusher:
                sid = pusher.push(doc, tess, scene="car").scene_id
            dress(http, sid, uuid_of, ("headlamp",))   # the demo's materials, floor and headlamp
            grid = http.post(f"/scenes/{sid}/sensors", json=GRID)
            grid.raise_for_status()
            url = f"/scenes/{sid}/sensors/{grid.json()['id']}/simulate"
            scene_effects = http.get(f"/scenes/{sid}").json()["effects"]
            bodies = {"default (polarized)": {"max_photons": photons},
                      "force_effects_off": {"max_photons": photons, "force_effects_off": ["polarization"]}}
            for b in bodies.values():   # compiled before timing
                http.post(url, json={**b, "max_photons": 2000}).raise_for_status()
            rates: dict[str, list[float]] = {n: [] for n in bodies}
            reasons = {}
            for r in range(rounds):
                for n in (list(bodies) if r % 2 == 0 else list(bodies)[::-1]):
                    a = http.post(url, json=bodies[n])
                    a.raise_for_status()
                    j = a.json()
                    rates[n].append(j["photons"] / (j["seconds"] - j["compile_seconds"]))
                    reasons[n] = j["effect_reasons"]["polarization"]
    med = {n: statistics.median(v) for n, v in rates.items()}
    return {"scene": "lumenlink demo car (paint, glass windscreen and lens, chrome reflector, tyres) on a concrete "
                     "floor, the 5000 cd headlamp spot; the floor grid sensor",
            "scene_effects": scene_effects, "photons": photons, "photons_per_second": med,
            "slowdown": med["force_effects_off"] / med["default (polarized)"], "polarization": reasons}


def microfacet_cost(rounds: int, photons: int) -> dict:
    """The cost of a `microfacet` bounce against the `mirror` and `lambertian` it generalises: a box room (4 x 4 x
    2.5 m) of the kind under a point light, photons/s of the forward kernel on one thread (every photon bounces until
    absorbed: reflectance 0.8)."""
    from bench.bench_transport import floor_points, room_scene
    from tracer.simulate import Simulation

    s, room = room_scene()
    pts, nrm = floor_points(3)
    lamp = [{"type": "point", "position": [2.0, 2.0, 2.5], "intensity_cd": 1000.0}]
    mats = {"lambertian": {"type": "lambertian", "reflectance": 0.8},
            "mirror": {"type": "mirror", "reflectance": 0.8},
            "microfacet": {"type": "microfacet", "alpha": 0.3, "reflectance": 0.8},
            "microfacet brushed Al": {"type": "microfacet", "alpha": 0.1, "alpha_y": 0.4, "axis": [1, 0, 0],
                                      "metal": [0.96, 6.69]}}
    sims = {n: Simulation(s, {room: m}, lamp) for n, m in mats.items()}
    for sim in sims.values():
        sim.illuminance(pts, nrm, max_photons=2000, estimator="forward")
    times = _interleaved({n: (lambda sim=sim: sim.illuminance(pts, nrm, max_photons=photons, estimator="forward"))
                          for n, sim in sims.items()}, rounds)
    return {"photons": photons, "photons_per_second": {n: photons / statistics.median(t) for n, t in times.items()},
            "ratio_to_mirror": _ratios(times, "mirror")}


def run(quick: bool = False) -> dict:
    import numba

    numba.set_num_threads(1)
    rounds = 3 if quick else 5
    out = {"diffuse_room": diffuse_room(), "glass_heavy": glass_heavy(rounds, 100_000 if quick else 400_000),
           "demo_car": demo_car(rounds, 100_000 if quick else 400_000),
           "microfacet_cost": microfacet_cost(rounds, 200_000 if quick else 1_000_000), "machine_threads": 1,
           "command": "flock /tmp/ll-cpu.lock .venv/bin/python -m bench.bench_polarization_default"
                      + (" --quick" if quick else "")}
    return out


if __name__ == "__main__":
    result = run(quick="--quick" in sys.argv)
    OUT.write_text(json.dumps(result, indent=2, default=float) + "\n")
    print(json.dumps(result, indent=2, default=float))
