"""Optical elements with an inside (issue 36): what preparing, holding and tracing micro-features costs.

1. Preparation: 10^6 dots of a density map (placed as blue noise, the default, and at random) and 10^6 listed points,
   prepared (median of 3), with their bytes per feature; a periodic layout's memory at 10^9 features (a grid: nothing
   per feature).
2. Rays that never enter an element pay nothing: 1M rays onto a floor beside a light guide, with the guide's dots as
   an element against the same guide plain (one thread, interleaved, median ratio of neighbouring passes).
3. Photons through a 10^6-dot light guide against the same guide with a plain face: forward photons per second,
   wall time, in turn (the plain guide keeps its light in by total internal reflection until the far edge).
4. Beside the same dots meshed: 20 x 20 domes as an element and meshed explicitly (~250k triangles): the
   bottom-level build, and closest hits per second of rays leaving the plate through its dotted face; and the same
   element whose dome is given as a mesh feature (48 x 8, 384 face planes: `tracer.elements.shapes.mesh`).
"""

from __future__ import annotations

import statistics
import sys
import time

import numpy as np

from bench.bench_spectral import _interleaved, _ratios

DOME = {"shape": "dome", "radius_mm": 0.08, "height_mm": 0.04}


def _box(lo, hi):
    from tracer.warmup import box

    return box(lo, hi)


def prepare_costs(repeat: int) -> dict:
    from tracer.elements import prepare

    density = {"type": "microstructure", "feature": DOME,
               "layout": {"type": "density", "origin_mm": [0, 0], "size_mm": [300.0, 200.0], "fill": [[0.667]],
                          "seed": 1, "pitch_mm": 0.2}}
    at_random = {**density, "layout": {**density["layout"], "placement": "random"}}
    rng = np.random.default_rng(3)
    side = 1000
    uv = np.column_stack([np.tile(np.arange(side), side), np.repeat(np.arange(side), side)]) * 0.2 + 0.1
    uv = uv + rng.uniform(-0.01, 0.01, uv.shape)
    points = {"type": "microstructure", "feature": DOME, "layout": {"type": "points", "uv_mm": uv.tolist()}}
    grid = {"type": "microstructure", "feature": {"shape": "dome", "radius_mm": 0.012, "height_mm": 0.005},
            "layout": {"type": "grid", "pitch_mm": [0.03, 0.03]}}   # 1.1e9 features on 1 m x 1 m
    out = {}
    for name, body in (("density map, blue noise", density), ("density map, random", at_random),
                       ("listed points", points), ("periodic grid", grid)):
        seconds, model = [], None
        for _ in range(repeat):
            t0 = time.perf_counter()
            model = prepare(body)
            seconds.append(time.perf_counter() - t0)
        assert model is not None
        features = model.features if model.features is not None else int((1000 / 0.03) ** 2)   # on 1 m x 1 m
        out[name] = {"features": features, "seconds": statistics.median(seconds), "bytes": model.nbytes,
                     "bytes_per_feature": model.nbytes / features}
    return out


def _guide_scene(with_dots: bool, size=(300e-3, 200e-3, 4e-3), floor: bool = False):
    from tracer.elements import prepare
    from tracer.scene import Scene

    s = Scene()
    v, t = _box([0, 0, 0], size)
    guide = s.add_instance(s.add_geometry(v, t), np.eye(4))
    if floor:
        fv, ft = _box([0.5, 0.0, -0.01], [1.5, 1.0, 0.0])
        s.add_instance(s.add_geometry(fv, ft), np.eye(4))
    if with_dots:
        dots = prepare({"type": "microstructure", "feature": DOME,
                        "layout": {"type": "density", "origin_mm": [0, 0], "size_mm": [size[0] * 1e3, size[1] * 1e3],
                                   "fill": [[0.667]], "seed": 1, "pitch_mm": 0.2}})
        s.set_element(guide, dots, facing=[0, 0, -1])
    s.commit()
    return s, guide


def rays_beside(rounds: int) -> dict:
    plain, _ = _guide_scene(False, floor=True)
    dotted, _ = _guide_scene(True, floor=True)
    rng = np.random.default_rng(5)
    n = 1_000_000
    o = np.column_stack([rng.uniform(0.5, 1.5, n), rng.uniform(0.0, 1.0, n), np.full(n, 1.0)])
    d = np.column_stack([rng.uniform(-0.2, 0.2, n), rng.uniform(-0.2, 0.2, n), -np.ones(n)])
    d = d / np.linalg.norm(d, axis=1)[:, None]
    plain.intersect(o[:1000], d[:1000], threads=1)
    dotted.intersect(o[:1000], d[:1000], threads=1)
    a, b = plain.intersect(o, d, threads=1), dotted.intersect(o, d, threads=1)
    assert np.array_equal(a.t, b.t)
    times = _interleaved({"plain guide": lambda: plain.intersect(o, d, threads=1),
                          "guide with 10^6 dots": lambda: dotted.intersect(o, d, threads=1)}, rounds)
    return {"rays": n, "seconds": {k: statistics.median(v) for k, v in times.items()},
            "ratio": _ratios(times, "plain guide")["guide with 10^6 dots"]}


def guide_photons(rounds: int, photons: int) -> dict:
    from tracer.simulate import Simulation

    out = {}
    sims = {}
    for name, dots in (("plain face", False), ("10^6 dots", True)):
        s, guide = _guide_scene(dots)
        sims[name] = Simulation(s, {guide: {"type": "dielectric", "ior": 1.49}},
                                [{"type": "collimated", "origin": [-0.002, 0.1, 0.001], "direction": [1, 0, 0.3],
                                  "radius": 0.0005, "illuminance_lx": 1e6}])
    grid = ([0.01, 0.01, 0.006], [0.0, 0.18, 0.0], [0.28, 0.0, 0.0], 3, 3)
    for sim in sims.values():
        sim.grid(*grid, max_photons=2000, estimator="forward")
    res = {}
    times: dict[str, list[float]] = {name: [] for name in sims}
    for r in range(rounds):   # wall time, in turn (the batches run on the backend's threads, not this one)
        for name in (list(sims) if r % 2 == 0 else list(sims)[::-1]):
            t0 = time.perf_counter()
            res[name] = sims[name].grid(*grid, max_photons=photons, seed=2, estimator="forward")
            times[name].append(time.perf_counter() - t0)
    for name, ts in times.items():
        out[name] = {"seconds": statistics.median(ts), "photons_per_second": photons / statistics.median(ts),
                     "lux_mean": float(np.mean(res[name].lux)),
                     "truncated": int(res[name].counters.get("truncated", 0))}
    out["ratio (dots / plain, seconds per photon)"] = _ratios(times, "plain face")["10^6 dots"]
    return out


def beside_meshed(rounds: int) -> dict:
    from bench.bench_spectral import ROOT

    sys.path.insert(0, str(ROOT))   # the meshed reference lives beside the tests that check the element against it
    from tests.tracer.elements.meshed_relief import domed_plate
    from tracer.elements import prepare
    from tracer.scene import Scene

    n, pitch = 20, 0.2e-3
    size = n * pitch
    meshed = Scene()
    v, t = domed_plate(n, pitch, 0.08e-3, 0.04e-3, 1e-3)
    meshed.add_instance(meshed.add_geometry(v, t), np.eye(4))
    built = meshed.commit()
    element = Scene()
    bv, bt = _box([0, 0, 0], [size, size, 1e-3])
    part = element.add_instance(element.add_geometry(bv, bt), np.eye(4))
    t0 = time.perf_counter()
    model = prepare({"type": "microstructure", "feature": DOME,
                     "layout": {"type": "grid", "pitch_mm": [0.2, 0.2]}})
    element.set_element(part, model, facing=[0, 0, -1])
    element_built = element.commit()
    element_seconds = time.perf_counter() - t0
    from tests.tracer.elements.test_mesh_feature import dome_mesh

    as_mesh = Scene()
    part = as_mesh.add_instance(as_mesh.add_geometry(bv, bt), np.eye(4))
    dome = dome_mesh(DOME["radius_mm"], DOME["height_mm"])
    as_mesh.set_element(part, prepare({"type": "microstructure", "feature": dome,
                                       "layout": {"type": "grid", "pitch_mm": [0.2, 0.2]}}), facing=[0, 0, -1])
    as_mesh.commit()
    rng = np.random.default_rng(9)
    k = 200_000
    o = np.column_stack([rng.uniform(0, size, k), rng.uniform(0, size, k), np.full(k, 0.5e-3)])
    d = np.column_stack([rng.uniform(-0.5, 0.5, k), rng.uniform(-0.5, 0.5, k), -np.ones(k)])
    d = d / np.linalg.norm(d, axis=1)[:, None]
    meshed.intersect(o[:100], d[:100], threads=1)
    element.intersect(o[:100], d[:100], threads=1)
    as_mesh.intersect(o[:100], d[:100], threads=1)
    times = _interleaved({"meshed": lambda: meshed.intersect(o, d, threads=1),
                          "element": lambda: element.intersect(o, d, threads=1),
                          "element, dome as a mesh feature": lambda: as_mesh.intersect(o, d, threads=1)}, rounds)
    return {"triangles": int(len(t)), "build_seconds": {"meshed": built.blas_seconds + built.tlas_seconds,
                                                        "element": element_seconds},
            "element_blas_seconds": element_built.blas_seconds,
            "rays_per_second": {n: k / statistics.median(ts) for n, ts in times.items()},
            "ratio (element / meshed, seconds)": _ratios(times, "meshed")["element"],
            "ratio (mesh feature / analytic dome, seconds)": _ratios(times, "element")[
                "element, dome as a mesh feature"]}


def run(quick: bool = False) -> dict:
    rounds = 3 if quick else 7
    result = {"prepare": prepare_costs(1 if quick else 3), "rays_beside": rays_beside(rounds),
              "guide": guide_photons(3 if quick else 5, 20_000 if quick else 100_000),
              "meshed": beside_meshed(rounds)}
    p, r, g, m = result["prepare"], result["rays_beside"], result["guide"], result["meshed"]
    lines = ["Preparation (median of 3) and memory per feature:", "",
             "| layout | features | seconds | bytes | bytes per feature |", "|---|---|---|---|---|"]
    lines += [f"| {k} | {v['features']:.3g} | {v['seconds']:.3f} | {v['bytes']} | {v['bytes_per_feature']:.3g} |"
              for k, v in p.items()]
    lines += ["", f"Rays that never enter an element ({r['rays']:,} rays onto a floor beside a 300 x 200 mm guide, "
                  f"one thread): with its 10^6 dots as an element {r['seconds']['guide with 10^6 dots']:.3f} s "
                  f"against {r['seconds']['plain guide']:.3f} s plain, ratio {r['ratio']:.3f}.",
              "", "Forward photons through the edge-lit guide (one beam into its edge, a 3 x 3 grid over it), wall "
                  "time on the machine's cores:", "",
              "| guide | photons/s | mean lx over it | truncated paths |", "|---|---|---|---|"]
    lines += [f"| {k} | {v['photons_per_second']:,.0f} | {v['lux_mean']:.4g} | {v['truncated']} |"
              for k, v in g.items() if isinstance(v, dict)]
    lines += ["", f"Seconds per photon, dots against plain: {g['ratio (dots / plain, seconds per photon)']:.2f} "
                  f"(the plain guide lights nothing over it: its light stays in by total internal reflection until "
                  f"it leaves by the far edge).",
              "", f"Beside the same dots meshed (20 x 20 domes, {m['triangles']:,} triangles): build "
                  f"{m['build_seconds']['meshed']:.2f} s meshed against {m['build_seconds']['element']:.4f} s as an "
                  f"element (prepare, split the plate, two small bottom levels); closest hits of rays leaving through "
                  f"the dotted face {m['rays_per_second']['element']:,.0f}/s as an element against "
                  f"{m['rays_per_second']['meshed']:,.0f}/s meshed (time ratio "
                  f"{m['ratio (element / meshed, seconds)']:.2f}); with the dome given as a mesh feature (48 x 8, "
                  f"384 face planes) {m['rays_per_second']['element, dome as a mesh feature']:,.0f}/s (time ratio "
                  f"{m['ratio (mesh feature / analytic dome, seconds)']:.2f} against the analytic dome)."]
    result["markdown"] = "\n".join(lines)
    return result


if __name__ == "__main__":
    import json

    print(json.dumps(run(quick="--quick" in sys.argv), indent=2, default=float))
