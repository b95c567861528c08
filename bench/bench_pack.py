"""Packing a light guide's dots (issue 41): the iterations it takes and what each costs, beside a full rebuild.

1. The demo guide (`lumenlink.guide_demo`: 120 x 80 x 4 mm PMMA, an edge LED, a white reflector, nine cells 3 mm
   over the lit face) through the REST API of a real service: a uniform start (fill 1.0, an 8 x 24 map) measured
   with a fresh seed, packed (``POST /elements/{id}/pack``) to min/max 0.95, the scene switched to the result, and
   measured again with another fresh seed. Per iteration: the figure ± error, photons, the element's update (prepare,
   set_element, commit, a new Simulation) and the measurement; the pack's full rebuild of its scene.
2. Incremental against a full rebuild in the tracer (median of 5): the element's update, against building the whole
   scene again (every geometry, instance and the element, commit, Simulation), for the guide alone and beside a
   part of 500k triangles (a housing's worth): the update does not grow with the rest of the scene.
"""

from __future__ import annotations

import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np


def through_service(photons: int, start_photons: int, max_iterations: int) -> dict[str, Any]:
    import httpx

    from lumenlink.client import Client
    from lumenlink.demo import running_service
    from lumenlink.guide_demo import pack_guide

    data = Path(tempfile.mkdtemp(prefix="lumenlink-bench-pack-"))
    try:
        with running_service(data) as url, Client(url) as ll, httpx.Client(base_url=url, timeout=900) as http:
            p = pack_guide(ll, http, None, photons=photons, start_photons=start_photons,
                           max_iterations=max_iterations)
    finally:
        shutil.rmtree(data, ignore_errors=True)
    r = p["pack"]
    hist = r["history"]
    return {"before": {k: v for k, v in p["before"].items() if k != "lux"}, "after": p["after"],
            "target": p["target"], "stopped": r["stopped"], "iterations": r["iterations"], "best": r["best"],
            "pack_uniformity": r["uniformity"], "pack_stderr": r["uniformity_stderr"], "history": hist,
            "rebuild_seconds": r["rebuild_seconds"], "update_seconds_median": statistics.median(
                h["update_seconds"] for h in hist),
            "measure_seconds_median": statistics.median(h["measure_seconds"] for h in hist),
            "pack_wall_seconds": p["pack_wall_seconds"], "features": hist[r["best"]]["features"]}


def _housing(n: int) -> tuple[np.ndarray, np.ndarray]:
    """A wavy sheet of about 2 n^2 triangles under the guide (a part the pack never touches), in mm."""
    x, y = np.meshgrid(np.linspace(-50, 170, n + 1), np.linspace(-50, 130, n + 1))
    v = np.column_stack([x.ravel(), y.ravel(), (-20 + np.sin(x / 7.0) * np.cos(y / 5.0)).ravel()])
    i = np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]
    a, b, c, d = i.ravel(), i.ravel() + 1, i.ravel() + n + 1, i.ravel() + n + 2
    return v.astype(np.float32), np.concatenate([np.column_stack([a, c, b]), np.column_stack([b, c, d])])


def incremental(repeat: int) -> dict[str, Any]:
    import tracer
    from lumenlink.guide_demo import DOT, EXITANCE, PITCH, SIZE, _box, _quad
    from tracer.elements import prepare
    from tracer.elements.pack import density_body
    from tracer.simulate import Simulation

    body = {"type": "microstructure", "feature": DOT, "relief": "bump",
            "layout": {"type": "density", "origin_mm": [0.0, 0.0], "size_mm": [SIZE[0], SIZE[1]],
                       "fill": [[1.0] * 24] * 8, "seed": 1, "pitch_mm": PITCH}}
    scale = np.diag([1e-3, 1e-3, 1e-3, 1.0])
    assign = {"facing": [0, 0, -1], "mm_per_unit": 1.0}
    out: dict[str, Any] = {}
    for name, extra in (("guide", None), ("guide + 500k-triangle part", _housing(500))):
        parts = {"guide": _box((0, 0, 0), SIZE), "led": _quad([-0.3, 1.0, 0.5], [0.0, 78.0, 0.0], [0.0, 0.0, 3.0]),
                 "reflector": _quad([-2.0, -2.0, -1.0], [0.0, 84.0, 0.0], [124.0, 0.0, 0.0])}
        if extra is not None:
            parts["housing"] = extra

        def simulation(s: Any, ids: dict[str, int]) -> Any:
            mats = {ids["guide"]: {"type": "dielectric", "ior": 1.49}, ids["led"]: {"type": "black"},
                    ids["reflector"]: {"type": "lambertian", "reflectance": 0.9}}
            lights = [{"type": "area", "instances": [ids["led"]], "exitance_lm_m2": EXITANCE}]
            return Simulation(s, mats, lights, default_material={"type": "lambertian", "reflectance": 0.5})

        def build(model: Any, parts: dict = parts) -> tuple[Any, dict[str, int]]:
            s = tracer.Scene()
            ids = {k: s.add_instance(s.add_geometry(v, t), scale) for k, (v, t) in parts.items()}
            s.set_element(ids["guide"], model, **assign)
            s.commit()
            simulation(s, ids)
            return s, ids

        start = prepare(body)
        s, ids = build(start)
        rng = np.random.default_rng(5)
        upd, full = [], []
        for _ in range(repeat):
            fill = rng.uniform(0.3, 1.0, (8, 24))
            t0 = time.perf_counter()
            model = prepare(density_body(body, fill))
            s.set_element(ids["guide"], model, **assign)
            s.commit()
            simulation(s, ids)
            upd.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            build(prepare(density_body(body, fill)))
            full.append(time.perf_counter() - t0)
        out[name] = {"triangles": int(sum(len(t) for _, t in parts.values())), "features": int(model.features or 0),
                     "update_seconds": statistics.median(upd), "rebuild_seconds": statistics.median(full),
                     "ratio (rebuild / update)": statistics.median(full) / statistics.median(upd)}
    return out


def run(quick: bool = False) -> dict:
    svc = through_service(100_000 if quick else 400_000, 50_000 if quick else 200_000, 4 if quick else 10)
    inc = incremental(2 if quick else 5)
    return {"service": svc, "incremental": inc, "markdown": markdown(svc, inc)}


def markdown(svc: dict[str, Any], inc: dict[str, Any]) -> str:
    """The REPORT.md section of a run's figures."""
    b, a = svc["before"], svc["after"]
    lines = [f"The demo guide (120 x 80 x 4 mm PMMA, edge LED, white reflector; nine cells 3 mm over the lit face) "
             f"through the REST API: a uniform start (fill 1.0 on an 8 x 24 map, {svc['features']:,} dots at the "
             f"end) packed to min/max {svc['target']:g}. Before, with a fresh seed: min/max {b['min_max']:.3f} ± "
             f"{b['min_max_stderr']:.3f}; after ({svc['stopped']}, {svc['iterations']} iterations, chosen "
             f"{svc['best']}), switched and measured with another fresh seed: min/max {a['min_max']:.3f} ± "
             f"{a['min_max_stderr']:.3f} (min/mean {a['min_mean']:.3f}); the pack's own figure "
             f"{svc['pack_uniformity']:.3f} ± {svc['pack_stderr']:.3f}; {svc['pack_wall_seconds']:.0f} s in all.", "",
             "| iteration | min/max | ± | photons | update (ms) | measurement (s) |", "|---|---|---|---|---|---|"]
    lines += [f"| {h['iteration']} | {h['uniformity']:.3f} | {h['stderr']:.3f} | {h['photons']:,} | "
              f"{h['update_seconds'] * 1000:.1f} | {h['measure_seconds']:.2f} |" for h in svc["history"]]
    lines += ["", f"An iteration's update (prepare the map, set_element, commit, a new Simulation) took "
                  f"{svc['update_seconds_median'] * 1000:.1f} ms (median) against "
                  f"{svc['rebuild_seconds'] * 1000:.1f} ms for the pack's full rebuild of its scene from the "
                  f"database (a scene of 16 triangles); the measurement dominates "
                  f"({svc['measure_seconds_median']:.1f} s median).", "",
              "In the tracer (median of 5), the element's update against building the whole scene again:", "",
              "| scene | triangles | update (s) | full rebuild (s) | rebuild / update |", "|---|---|---|---|---|"]
    lines += [f"| {k} | {v['triangles']:,} | {v['update_seconds']:.4f} | {v['rebuild_seconds']:.3f} | "
              f"{v['ratio (rebuild / update)']:.0f} |" for k, v in inc.items()]
    return "\n".join(lines)


if __name__ == "__main__":
    import json

    print(json.dumps(run(quick="--quick" in sys.argv), indent=2, default=float))
