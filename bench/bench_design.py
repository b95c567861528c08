"""The design loop over an element's parameters (issue 53): why it reads every candidate with the same random numbers,
and what it does on the demo guide.

1. Common random numbers against independent seeds: the demo guide (`lumenlink.guide_demo`: 120 x 80 x 4 mm PMMA,
   edge LED, white reflector, nine cells 3 mm over the lit face) with its dots 0.08 mm and 0.10 mm high, read in
   pairs: with one seed for both (what `tracer.elements.design` does) and with two seeds. The spread (standard
   deviation over the pairs) of the difference in each objective, against the two readings' own standard errors
   combined: how much smaller a difference the loop can tell from noise.
2. The loop on the demo guide from dots 0.04 mm high: their height swept over five values for the most light on the
   lit face (the mean of the nine cells), the density map packed to min/max 0.9 before and after the sweep; the
   gain confirmed on a fresh seed, with its error bar, and the seconds the loop took.
"""

from __future__ import annotations

import statistics
import time
from typing import Any

import numpy as np

HEIGHTS = (0.04, 0.07, 0.1, 0.13, 0.16)


def _guide(height: float) -> tuple[Any, int, Any, dict, dict]:
    """(scene, guide instance, simulation(scene), starting element body, set_element keywords)."""
    import tracer
    from lumenlink.guide_demo import DOT, EXITANCE, PITCH, SIZE, _box, _quad
    from tracer.simulate import Simulation

    parts = {"guide": _box((0, 0, 0), SIZE), "led": _quad([-0.3, 1.0, 0.5], [0.0, 78.0, 0.0], [0.0, 0.0, 3.0]),
             "reflector": _quad([-2.0, -2.0, -1.0], [0.0, 84.0, 0.0], [124.0, 0.0, 0.0])}
    s = tracer.Scene()
    scale = np.diag([1e-3, 1e-3, 1e-3, 1.0])
    ids = {k: s.add_instance(s.add_geometry(v, t), scale) for k, (v, t) in parts.items()}
    body = {"type": "microstructure", "feature": {**DOT, "height_mm": height}, "relief": "bump",
            "layout": {"type": "density", "origin_mm": [0.0, 0.0], "size_mm": [SIZE[0], SIZE[1]],
                       "fill": [[0.6] * 24] * 8, "seed": 1, "pitch_mm": PITCH}}
    mats = {ids["guide"]: {"type": "dielectric", "ior": 1.49}, ids["led"]: {"type": "black"},
            ids["reflector"]: {"type": "lambertian", "reflectance": 0.9}}
    lights = [{"type": "area", "instances": [ids["led"]], "exitance_lm_m2": EXITANCE}]

    def simulation(scene: Any) -> Any:
        return Simulation(scene, mats, lights, default_material={"type": "lambertian", "reflectance": 0.5})

    return s, ids["guide"], simulation, body, {"facing": [0, 0, -1], "mm_per_unit": 1.0}


def common_random_numbers(pairs: int, photons: int) -> dict[str, Any]:
    from lumenlink.guide_demo import GRID
    from tracer.elements import prepare
    from tracer.elements.design import objective_of
    from tracer.elements.pack import Reading, read

    s, guide, simulation, body, assign = _guide(0.08)
    models = {h: prepare({**body, "feature": {**body["feature"], "height_mm": h}}) for h in (0.08, 0.1)}

    def reading(h: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
        s.set_element(guide, models[h], **assign)
        s.commit()
        values, err, _ = read(simulation(s), GRID, Reading(), photons, seed, None, None)
        return values, err

    out: dict[str, Any] = {}
    diffs: dict[str, dict[str, list[float]]] = {o: {"same seed": [], "two seeds": [], "own": []}
                                                for o in ("mean", "min_max")}
    for k in range(pairs):
        a, ea = reading(0.08, 11 + k)
        b, eb = reading(0.1, 11 + k)
        c, ec = reading(0.1, 5011 + k)
        for o in diffs:
            (va, sa), (vb, sb), (vc, _) = (objective_of(a, ea, o), objective_of(b, eb, o), objective_of(c, ec, o))
            diffs[o]["same seed"].append(vb - va)
            diffs[o]["two seeds"].append(vc - va)
            diffs[o]["own"].append(float(np.hypot(sa, sb)))
    for o, d in diffs.items():
        same, two = statistics.stdev(d["same seed"]), statistics.stdev(d["two seeds"])
        out[o] = {"difference_mean": statistics.mean(d["two seeds"]), "sd_same_seed": same, "sd_two_seeds": two,
                  "own_stderr_combined": statistics.median(d["own"]), "ratio (two seeds / same seed)": two / same}
    return {"pairs": pairs, "photons": photons, "objectives": out}


def loop(photons: int, pack_iterations: int) -> dict[str, Any]:
    from lumenlink.guide_demo import GRID
    from tracer.elements import prepare
    from tracer.elements.design import Parameter, design

    s, guide, simulation, body, assign = _guide(0.04)
    stages: list[tuple[str, float]] = []
    t0 = time.perf_counter()
    res = design(s, guide, prepare(body), GRID, simulation, assign=assign, objective="mean", photons=photons,
                 seed=3, parameters=[Parameter("feature.height_mm", HEIGHTS)],
                 pack_options={"target": 0.9, "figure": "min_max", "max_iterations": pack_iterations,
                               "photons": photons, "max_photons": 4 * photons},
                 progress=lambda p: stages.append((p["stage"], p["seconds"])))
    c = res.confirmation or {}
    return {"values": res.values, "baseline": res.baseline, "confirmation": c, "stopped": res.stopped,
            "candidates": [x.public() for x in res.candidates],
            "packs": [{"stopped": p.stopped, "iterations": len(p.history), "min_max": p.history[p.best].uniformity,
                       "stderr": p.history[p.best].stderr, "seconds": p.seconds} for p in res.packs],
            "seconds": time.perf_counter() - t0, "photons": photons}


def run(quick: bool = False) -> dict:
    crn = common_random_numbers(4 if quick else 8, 50_000 if quick else 100_000)
    lp = loop(50_000 if quick else 100_000, 2 if quick else 4)
    return {"common_random_numbers": crn, "loop": lp, "markdown": markdown(crn, lp)}


def markdown(crn: dict[str, Any], lp: dict[str, Any]) -> str:
    """The REPORT.md section of a run's figures."""
    lines = [f"Common random numbers (`tracer.elements.design`): the demo guide's dots 0.08 and 0.10 mm high, "
             f"{crn['pairs']} pairs of readings of the nine cells ({crn['photons']:,} photons each), the difference "
             f"of each objective with one seed for both against two seeds:", "",
             "| objective | mean difference | sd, same seed | sd, two seeds | two / same | readings' own σ combined |",
             "|---|---|---|---|---|---|"]
    for o, r in crn["objectives"].items():
        lines.append(f"| {o} | {r['difference_mean']:.4g} | {r['sd_same_seed']:.3g} | {r['sd_two_seeds']:.3g} | "
                     f"{r['ratio (two seeds / same seed)']:.2f} | {r['own_stderr_combined']:.3g} |")
    b, c = lp["baseline"], lp["confirmation"]
    lines += ["", f"The loop on the demo guide from dots 0.04 mm high (their height over {list(HEIGHTS)} mm for the "
                  f"most light on the lit "
                  f"face, the nine cells' mean, lx; the map packed to min/max 0.9 before and after; "
                  f"{lp['photons']:,} photons a reading): {lp['stopped']}, {lp['seconds']:.0f} s; chose "
                  f"{lp['values']}. Baseline {b['objective']:.4g} ± {b['stderr']:.2g} lx at the sweep's seed.", "",
              "| height (mm) | mean (lx) | ± | seconds |", "|---|---|---|---|"]
    for x in lp["candidates"]:
        h = x["values"]["feature.height_mm"]
        if x["refused"]:
            lines.append(f"| {h:g} | refused: {x['refused'][:60]} | | |")
        else:
            lines.append(f"| {h:g} | {x['objective']:.4g} | {x['stderr']:.2g} | {x['seconds']:.1f} |")
    if c:
        lines += ["", f"Confirmed on a fresh seed: baseline {c['baseline']:.4g} ± {c['baseline_stderr']:.2g}, "
                      f"result {c['objective']:.4g} ± {c['stderr']:.2g} lx; gain {c['improvement']:.4g} ± "
                      f"{c['improvement_stderr']:.2g} (improved beyond 2σ: {c['improved']})."]
    packs = "; ".join(f"{p['stopped']} after {p['iterations']} iterations, min/max {p['min_max']:.3f} ± "
                      f"{p['stderr']:.3f}, {p['seconds']:.0f} s" for p in lp["packs"])
    lines += ["", f"Packs: {packs}."]
    return "\n".join(lines)
