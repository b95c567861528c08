"""Area lights behind glass and in mirrors: light tracing from them (`tracer.transport.light_tracing`, chosen per
query by `tracer.transport.rounds.area_light_pilot`) against paths from the eye alone, side by side in one run.

Three camera scenes, each image judged against its reference:

1. An LED behind a glass pane lighting a wall 2 m away (`tests/tracer/sensors/test_light_tracing.py`'s scene):
   the closed form ρ/π × T(θ) × E(θ). No shadow ray passes the pane; paths from the eye find the LED through it only
   by a BSDF sample that hits 1 cm² at 2 m.
2. A 10 cm square area light over a floor beside a mirror (the same file's): the closed form ρ(E + rE')/π, whose
   mirrored share (12-25 % of each pixel) paths from the eye find only by hitting the small emitter through the
   mirror.
3. The demo light guide (`lumenlink.guide_demo`'s, dots 0.08 mm high) seen from 0.3 m: its LED lights the face
   only through the guide; light tracing joins the reflector sheet under it to the eye through the guide's two flat
   faces (`tracer.transport.through_flat`, since 2026-12-08: before, only the reflector's rim could be joined).
   Reference: a long run.

For each, at each budget (seconds), the image with paths from the eye alone (``AREA_LIGHT_TRACING`` off, the code
before this bench) and as a query now runs: the median and 95th percentile pixel error |L - L_ref| / L_ref, the
median pixel standard error the answer states, and the share of pixels within 2 of its stated σ of the reference
(about 95 % where the error bar is honest).

    python -m bench.run --only area_lights        (--quick: shorter budgets and reference)
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

BUDGETS = (1.0, 4.0)
QUICK_BUDGETS = (1.0,)
SIZE = (64, 48)
GUIDE_REFERENCE_SECONDS = {False: 120.0, True: 40.0}   # by quick


def _scenes() -> list[tuple[str, Any, dict, Any]]:
    """(name, simulation, camera body, reference image or a function of the simulation giving one)."""
    from tests.tracer.sensors import test_light_tracing as lt

    w, h = SIZE
    wall_cam = dict(lt.WALL_CAMERA, width=w, height=h)
    floor_cam = dict(lt.CAMERA, width=w, height=h)
    guide_sim, guide_cam = _guide()
    return [("LED behind a glass pane, wall 2 m away", lt.led_sim(), wall_cam, lt.wall_pixel_means(wall_cam, n=8)),
            ("area light beside a mirror, floor", lt.mirror_sim(area=True), floor_cam,
             lt.pixel_means(floor_cam, area=True, n=8)),
            ("demo light guide from 0.3 m", guide_sim, guide_cam, None)]


def _guide() -> tuple[Any, dict]:
    from bench.bench_design import _guide as guide
    from tracer.elements import prepare

    s, inst, simulation, body, assign = guide(0.08)
    s.set_element(inst, prepare(body), **assign)
    s.commit()
    cam = {"type": "camera", "position": [0.06, 0.04, 0.3], "look_at": [0.06, 0.04, 0.0], "up": [0, 1, 0],
           "fov_deg": 18.0, "width": 40, "height": 30}
    return simulation(s), cam


def _image(sim: Any, cam: dict, seconds: float, traced: bool, seed: int) -> dict[str, Any]:
    import tracer.transport.light_tracing as light_tracing

    light_tracing.AREA_LIGHT_TRACING = traced
    try:
        r = sim.run(cam, max_seconds=seconds, seed=seed)
    finally:
        light_tracing.AREA_LIGHT_TRACING = True
    return {"lum": np.asarray(r.luminance), "stderr": np.asarray(r.stderr), "seconds": r.seconds,
            "paths": int(r.photons), "light_paths": int(r.counters.get("light_paths", 0)),
            "strategy": r.strategy}


def _decision(strategy: str) -> str:
    """What the pilot decided, from the answer's strategy."""
    mark = "; area lights "
    return strategy.split(mark, 1)[1] if mark in strategy else "(no pilot ran)"


def judge(img: dict[str, Any], ref: np.ndarray) -> dict[str, float]:
    """The errors of an image against the reference, over the pixels the reference lights."""
    lit = ref > 0
    err = np.abs(img["lum"] - ref)[lit] / ref[lit]
    se = img["stderr"][lit]
    return {"median": float(np.median(err)), "p95": float(np.percentile(err, 95)),
            "median_rel_stderr": float(np.median(se / ref[lit])),
            "within_2_sigma": float(np.mean(np.abs(img["lum"] - ref)[lit] <= 2 * se))}


def run(quick: bool = False) -> dict:
    budgets = QUICK_BUDGETS if quick else BUDGETS
    cases = []
    for name, sim, cam, ref in _scenes():
        _image(sim, dict(cam, width=4, height=3), 0.2, True, 1)   # compile or load the kernel outside the timing
        case: dict[str, Any] = {"scene": name, "width": cam["width"], "height": cam["height"], "rows": []}
        if ref is None:
            t = time.perf_counter()
            long = _image(sim, cam, GUIDE_REFERENCE_SECONDS[quick], True, 99)
            ref = long["lum"]
            lit = ref > 0
            case["reference"] = {"seconds": time.perf_counter() - t, "paths": long["paths"],
                                 "median_rel_stderr": float(np.median(long["stderr"][lit] / ref[lit]))}
        else:
            case["reference"] = {"closed_form": True}
        for budget in budgets:
            for traced in (False, True):
                img = _image(sim, cam, budget, traced, 7)
                case["rows"].append({"budget": budget, "light_tracing_of_area_lights": traced,
                                     "seconds": img["seconds"], "paths": img["paths"],
                                     "light_paths": img["light_paths"], **judge(img, ref),
                                     "decision": _decision(img["strategy"]) if traced else ""})
        cases.append(case)
    return {"cases": cases, "markdown": markdown(cases)}


def markdown(cases: list[dict]) -> str:
    lines = ["Camera images with paths from the eye alone (before) and as a query runs now (light tracing from the "
             "area lights where its pilot finds it pays), each against its reference: the closed form, or a long "
             "run. Errors |L - L_ref| / L_ref over the lit pixels; *within 2σ*: the pixels whose stated standard "
             "error covers the reference twice over (about 95 % if the error bar is honest). "
             "`lumenlink bench --only area_lights`.", ""]
    for case in cases:
        ref = case["reference"]
        how = ("closed form" if ref.get("closed_form") else
               f"our run of {ref['seconds']:.0f} s ({ref['paths']:,} paths, median pixel stderr "
               f"{100 * ref['median_rel_stderr']:.2f} %)")
        lines += [f"**{case['scene']}**, {case['width']} x {case['height']}; reference: {how}.", "",
                  "| budget s | strategy | seconds | paths from the eye | light paths | median error | 95th pct "
                  "error | stated median stderr | within 2σ |", "| ---: | --- | ---: | ---: | ---: | ---: | ---: | "
                  "---: | ---: |"]
        for r in case["rows"]:
            strategy = "eye paths + pilot" if r["light_tracing_of_area_lights"] else "eye paths alone"
            lines.append(f"| {r['budget']:g} | {strategy} | {r['seconds']:.2f} | {r['paths']:,} | "
                         f"{r['light_paths']:,} | {100 * r['median']:.2f} % | {100 * r['p95']:.2f} % | "
                         f"{100 * r['median_rel_stderr']:.2f} % | {100 * r['within_2_sigma']:.0f} % |")
        decision = next((r["decision"] for r in case["rows"] if r["decision"]), "")
        lines += ["", f"The pilot: area lights {decision}", ""]
    return "\n".join(lines)
