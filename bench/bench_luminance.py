"""Camera images of the diffuse room beside Radiance's `rpict` (pyradiance), in the same run.

The room of `bench.bench_transport`: 4 × 4 × 3 m, Lambertian walls, floor and ceiling (ρ = 0.5), one 1000 cd point
source at (2, 2, 2.5) (Radiance: a 1 cm light sphere of the same intensity, plastic walls). The camera stands at
(0.3, 0.3, 1.5) and looks at (3, 3, 0.6) with a 50° vertical field of view (the lamp is out of view).

- Ours: the first coarse image (one pass at ~4 paths per pixel, the kernel already loaded) and its seconds; the
  median pixel relative error (stderr / luminance) of a run of a fixed time budget, and the time to 2 % median pixel
  error extrapolated from it by 1/√paths (each pixel's error falls so; the run's own figure is given beside);
- Radiance: `rpict -ab 5 -ps 1 -pj 0` (one ray through each pixel's centre, five ambient bounces, its irradiance
  cache; no error bar), its seconds, and per pixel the relative difference from ours and the share of pixels whose
  difference lies within 4 of our standard errors plus 2 % (its irradiance-cache interpolation and centre-ray
  sampling are biases that carry no error bar of their own).

    NUMBA_CACHE_DIR=... python -m bench.run --only luminance    (or: python bench/bench_luminance.py [--full])
"""

from __future__ import annotations

import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.bench_transport import INTENSITY, LIGHT, RADIANCE_EFFICACY, RHO, radiance_room, room_scene  # noqa: E402

EYE, LOOK, FOV = (0.3, 0.3, 1.5), (3.0, 3.0, 0.6), 50.0
TARGET = 0.02
RAD_PARAMS = ["-ab", "5", "-ps", "1", "-pj", "0", "-pa", "0"]


def camera(w: int, h: int) -> dict:
    return {"type": "camera", "position": list(EYE), "look_at": list(LOOK), "up": [0.0, 0.0, 1.0], "fov_deg": FOV,
            "width": w, "height": h}


def median_rel(lum: np.ndarray, err: np.ndarray) -> float:
    rel = err / np.where(lum > 0, lum, np.nan)
    return float(np.nanmedian(rel))


def ours(w: int, h: int, budget: float) -> tuple[dict, np.ndarray, np.ndarray]:
    from tracer.simulate import Simulation

    s, room = room_scene()
    sim = Simulation(s, {room: {"type": "lambertian", "reflectance": RHO}},
                     [{"type": "point", "position": list(LIGHT), "intensity_cd": INTENSITY}])
    t = time.perf_counter()
    sim.run(camera(2, 2), max_photons=64)   # compile or load the kernel
    load = time.perf_counter() - t
    t = time.perf_counter()
    coarse = sim.run(camera(w, h), max_photons=4 * w * h, seed=1)
    first = time.perf_counter() - t
    t = time.perf_counter()
    r = sim.run(camera(w, h), max_seconds=budget, seed=2)
    wall = time.perf_counter() - t
    m = median_rel(r.luminance, r.stderr)
    return ({"kernel_load_seconds": load, "first_image_seconds": first, "first_image_paths": int(coarse.photons),
             "first_image_median_rel": median_rel(coarse.luminance, coarse.stderr), "budget_seconds": budget,
             "run_seconds": wall, "paths": int(r.photons), "median_rel": m,
             "seconds_to_2pct": wall * (m / TARGET) ** 2 if m > TARGET else wall,
             "mean_cd_m2": float(r.luminance.mean())}, r.luminance, r.stderr)


def radiance(w: int, h: int) -> tuple[dict, np.ndarray | None]:
    try:
        import pyradiance as pr
    except Exception as exc:   # an optional peer: say why it did not run
        return {"error": f"pyradiance could not be imported: {exc!r}"}, None
    vh = 2 * math.degrees(math.atan(math.tan(math.radians(FOV / 2)) * w / h))
    d = np.subtract(LOOK, EYE)
    view = ["-vtv", "-vp", *map(str, EYE), "-vd", *map(str, d), "-vu", "0", "0", "1", "-vv", str(FOV), "-vh",
            f"{vh:.9g}"]
    with tempfile.TemporaryDirectory() as tmp:
        try:
            octree = radiance_room(Path(tmp))
            t = time.perf_counter()
            pic = pr.rpict(view, octree, xres=w, yres=h, params=RAD_PARAMS)
            seconds = time.perf_counter() - t
            raw = pr.pvalue(pic, header=False, resstr=False, dataonly=True)
        except Exception as exc:
            return {"error": f"rpict failed: {exc!r}"}, None
    rgb = np.array([float(x) for x in raw.decode().split()]).reshape(h, w, 3)
    lum = RADIANCE_EFFICACY * (0.265 * rgb[..., 0] + 0.670 * rgb[..., 1] + 0.065 * rgb[..., 2])
    return {"params": RAD_PARAMS, "seconds": seconds, "mean_cd_m2": float(lum.mean())}, lum


def case(w: int, h: int, budget: float) -> dict:
    mine, lum, err = ours(w, h, budget)
    rad, rlum = radiance(w, h)
    out = {"width": w, "height": h, "ours": mine, "radiance": rad}
    if rlum is not None:
        rel = np.abs(rlum - lum) / np.where(lum > 0, lum, np.nan)
        within = np.abs(rlum - lum) <= 4 * err + 0.02 * lum
        out["agreement"] = {"median_rel_difference": float(np.nanmedian(rel)),
                            "p95_rel_difference": float(np.nanpercentile(rel, 95)),
                            "mean_ratio_radiance_to_ours": float(rlum.mean() / lum.mean()),
                            "share_within_4sigma_plus_2pct": float(within.mean())}
    return out


def run(quick: bool) -> dict:
    sizes = [(160, 120, 4.0)] if quick else [(160, 120, 8.0), (320, 240, 16.0)]
    cases = [case(w, h, b) for w, h, b in sizes]
    return {"cases": cases, "markdown": markdown(cases)}


def markdown(cases: list[dict]) -> str:
    md = ["Diffuse room (4 × 4 × 3 m, ρ = 0.5, 1000 cd at (2, 2, 2.5)), camera at (0.3, 0.3, 1.5) looking at "
          "(3, 3, 0.6), 50° vertical. Ours: paths from the eye, the kernel loaded; time to 2 % median pixel error "
          "extrapolated by 1/√paths from the budget run. Radiance: `rpict -ab 5 -ps 1 -pj 0` (one centre ray a "
          "pixel, irradiance cache, one process).", "",
          "| image | first image s (paths) | budget run s: median error | to 2 % s | rpict s | median \\|Δ\\|/L | "
          "95th pct | mean ratio rpict/ours | pixels within 4σ + 2 % |",
          "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for c in cases:
        o, r, a = c["ours"], c["radiance"], c.get("agreement")
        rad = f"{r['seconds']:.1f}" if "seconds" in r else f"did not run: {r.get('error')}"
        agree = (f"{100 * a['median_rel_difference']:.1f} % | {100 * a['p95_rel_difference']:.1f} % | "
                 f"{a['mean_ratio_radiance_to_ours']:.3f} | {100 * a['share_within_4sigma_plus_2pct']:.0f} %"
                 if a else "— | — | — | —")
        md.append(f"| {c['width']}×{c['height']} | {o['first_image_seconds']:.2f} ({o['first_image_paths']:,}) | "
                  f"{o['run_seconds']:.1f}: {100 * o['median_rel']:.1f} % | {o['seconds_to_2pct']:.0f} | {rad} | "
                  f"{agree} |")
    return "\n".join(md)


if __name__ == "__main__":
    result = run(quick="--full" not in sys.argv)
    print(result["markdown"])
