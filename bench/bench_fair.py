"""Luminance images to the same error as Radiance, both judged against a converged reference (issue 50, its first
step: a fair benchmark before any variance reduction).

The diffuse room and camera of `bench.bench_luminance` (Lambertian walls rho = 0.5, a 1000 cd point lamp out of
view), at ``W x H`` pixels. In one run:

1. The reference: our own path tracing for ``REFERENCE_SECONDS`` (its median pixel standard error is stated: the
   floor under every error below), cross-checked against ``rpict`` at its highest settings here.
2. Ours at budgets of 0.5 s to 16 s, each image's error against the reference: the median and the 95th percentile
   over the pixels of |L - L_ref| / L_ref, and its own median standard error.
3. ``rpict`` at the settings people use (``-ab`` 5 and 8; ``-aa`` 0.1 (its default), 0.05, 0.02; raised
   ``-ad``/``-as``), one centre ray per pixel (``-ps 1 -pj 0``), each image's seconds and the same two errors.
4. Equal error: for each rpict setting, the seconds ours needs to reach its median (and 95th percentile) error, from
   ours' curve (error = c / sqrt(seconds), c fitted over the budgets), and the ratio ours / rpict.

Pixels where the room's walls meet are in both: a centre ray sees one wall, our pixel the mean over its area; that
edge term is part of rpict's error here, and it is what the 95th percentile mostly shows.

    python -m bench.run --only fair        (--quick: 40 x 30, a shorter reference)
"""

from __future__ import annotations

import math
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.bench_luminance import camera, rpict_luminance, rpict_view  # noqa: E402
from bench.bench_transport import INTENSITY, LIGHT, RHO, radiance_room, room_scene  # noqa: E402

BUDGETS = (0.5, 1.0, 2.0, 4.0, 8.0, 16.0)
RPICT = {
    "-ab 5 -aa 0.1 (default)": ["-ab", "5"],
    "-ab 5 -aa 0.05": ["-ab", "5", "-aa", "0.05"],
    "-ab 5 -aa 0.02": ["-ab", "5", "-aa", "0.02"],
    "-ab 8 -aa 0.1": ["-ab", "8"],
    "-ab 8 -aa 0.02 -ad 2048 -as 1024": ["-ab", "8", "-aa", "0.02", "-ad", "2048", "-as", "1024"],
}
#: the cross-check of the reference: rpict as high as a few minutes allow here (8 bounces, a fine ambient cache, many
#: divisions; -aa 0.01 -ad 8192 had not finished 80 x 60 after 4 minutes)
RPICT_HIGHEST = ["-ab", "8", "-aa", "0.02", "-ad", "4096", "-as", "2048", "-ar", "512"]
#: seconds one rpict may take; a setting that takes longer is reported as such
RPICT_TIMEOUT = {"setting": 150.0, "highest": 400.0}
CENTRE_RAY = ["-ps", "1", "-pj", "0", "-pa", "0"]


def errors(lum: np.ndarray, ref: np.ndarray) -> dict[str, float]:
    """Median and 95th percentile over the pixels of |L - L_ref| / L_ref."""
    rel = np.abs(lum - ref) / np.where(ref > 0, ref, np.nan)
    return {"median": float(np.nanmedian(rel)), "p95": float(np.nanpercentile(rel, 95))}


def coverage(lum: np.ndarray, err: np.ndarray, ref: np.ndarray, ref_err: np.ndarray) -> float:
    """The share of the lit pixels whose error against the reference lies within 2 combined standard errors
    (the image's own and the reference's): about 95 % where the error bars are honest."""
    lit = ref > 0
    return float(np.mean(np.abs(lum - ref)[lit] <= 2 * np.hypot(err, ref_err)[lit]))


def ours_images(w: int, h: int, reference_seconds: float) -> tuple[dict, np.ndarray, list[dict]]:
    from tracer.simulate import Simulation

    s, room = room_scene()
    sim = Simulation(s, {room: {"type": "lambertian", "reflectance": RHO}},
                     [{"type": "point", "position": list(LIGHT), "intensity_cd": INTENSITY}])
    sim.run(camera(2, 2), max_photons=64)   # compile or load the kernel first
    t = time.perf_counter()
    ref = sim.run(camera(w, h), max_seconds=reference_seconds, seed=1000)
    reference = {"seconds": time.perf_counter() - t, "paths": int(ref.photons),
                 "median_rel_stderr": float(np.nanmedian(ref.stderr / np.where(ref.luminance > 0, ref.luminance,
                                                                                 np.nan)))}
    rows = []
    for k, budget in enumerate(BUDGETS):
        t = time.perf_counter()
        r = sim.run(camera(w, h), max_seconds=budget, seed=k + 1)
        seconds = time.perf_counter() - t
        own = float(np.nanmedian(r.stderr / np.where(r.luminance > 0, r.luminance, np.nan)))
        rows.append({"budget": budget, "seconds": seconds, "paths": int(r.photons), "median_rel_stderr": own,
                     "within_2_sigma": coverage(r.luminance, r.stderr, ref.luminance, ref.stderr),
                     **errors(r.luminance, ref.luminance)})
    return reference, ref.luminance, rows


def rpict_image(w: int, h: int, params: list[str], octree: Path, timeout: float) -> tuple[float, np.ndarray | None]:
    """rpict's image (cd/m²) and its seconds; None for the image where it took longer than ``timeout`` s."""
    import subprocess

    import pyradiance as pr

    cmd = [str(Path(pr.__file__).parent / "bin" / "rpict"), *rpict_view(w, h), "-x", str(w), "-y", str(h), *params,
           *CENTRE_RAY, str(octree)]
    t = time.perf_counter()
    try:
        pic = subprocess.run(cmd, check=True, capture_output=True, timeout=timeout).stdout
    except subprocess.TimeoutExpired:
        return time.perf_counter() - t, None
    return time.perf_counter() - t, rpict_luminance(pic, w, h)


def fit(rows: list[dict], key: str) -> float:
    """c of error = c / sqrt(seconds), least squares in log over ours' budgets."""
    return float(math.exp(statistics.fmean(math.log(r[key]) + 0.5 * math.log(r["seconds"]) for r in rows)))


def run(quick: bool = False) -> dict:
    try:
        import pyradiance  # noqa: F401
    except Exception as exc:   # an optional peer (the bench extra): say why it did not run
        return {"skipped": f"pyradiance: {exc!r}", "markdown": f"Not run: pyradiance is missing ({exc!r}); "
                                                               "`pip install -e '.[bench]'`."}
    w, h = (40, 30) if quick else (80, 60)
    reference_seconds = 30.0 if quick else 240.0
    reference, ref, ours = ours_images(w, h, reference_seconds)
    out: dict[str, Any] = {"width": w, "height": h, "reference": reference, "ours": ours, "rpict": []}
    c = {key: fit(ours, key) for key in ("median", "p95")}
    with tempfile.TemporaryDirectory() as tmp:
        octree = radiance_room(Path(tmp))
        seconds, lum = rpict_image(w, h, RPICT_HIGHEST, octree, RPICT_TIMEOUT["highest"])
        reference["rpict_highest"] = {"params": " ".join(RPICT_HIGHEST), "seconds": seconds,
                                      **(errors(lum, ref) | {"mean_ratio": float(lum.mean() / ref.mean())}
                                         if lum is not None else {"timed_out": True})}
        for name, params in RPICT.items():
            seconds, lum = rpict_image(w, h, params, octree, RPICT_TIMEOUT["setting"])
            if lum is None:
                out["rpict"].append({"params": name, "seconds": seconds, "timed_out": True})
                continue
            e = errors(lum, ref)
            equal = {key: (c[key] / e[key]) ** 2 for key in ("median", "p95")}   # ours' seconds to rpict's error
            out["rpict"].append({"params": name, "seconds": seconds, **e, "mean_ratio": float(lum.mean() / ref.mean()),
                                 "ours_seconds_at_equal_median": equal["median"],
                                 "ours_seconds_at_equal_p95": equal["p95"]})
    out["fit"] = c
    out["markdown"] = markdown(out)
    return out


def markdown(out: dict) -> str:
    ref = out["reference"]
    hi = ref["rpict_highest"]
    check = (f"differs from it by {100 * hi['median']:.2f} % median, {100 * hi['p95']:.2f} % at the 95th percentile, "
             f"mean ratio {hi['mean_ratio']:.4f}" if not hi.get("timed_out") else "had not finished")
    lines = [f"The diffuse room at {out['width']} x {out['height']} (`bench.bench_luminance`'s camera), every image "
             "judged against one reference: ours, "
             f"{ref['seconds']:.0f} s and {ref['paths']:,} paths, median pixel standard error "
             f"{100 * ref['median_rel_stderr']:.2f} % (the floor under every error below). Cross-check: rpict "
             f"`{hi['params']}` took {hi['seconds']:.1f} s and {check}. Errors are |L - L_ref| / L_ref over the "
             "pixels. `lumenlink bench --only fair`.", "",
             "Ours, path tracing from the eye, by time budget:", "",
             "| budget s | seconds | paths | median error | 95th pct error | own median stderr | within 2σ |",
             "| ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in out["ours"]:
        lines.append(f"| {r['budget']:g} | {r['seconds']:.2f} | {r['paths']:,} | {100 * r['median']:.2f} % | "
                     f"{100 * r['p95']:.2f} % | {100 * r['median_rel_stderr']:.2f} % | "
                     f"{100 * r['within_2_sigma']:.1f} % |")
    lines += ["", "*Within 2σ*: the share of pixels whose error lies within twice the combined standard error (the "
              "image's stated one and the reference's): about 95 % where the error bars are honest (issue 50 asks "
              "90-98 %).", "", f"Fitted: median error = {out['fit']['median']:.4f} / sqrt(s), 95th percentile = "
              f"{out['fit']['p95']:.4f} / sqrt(s). rpict (one centre ray a pixel) at the settings people use, and "
              "the seconds ours needs for the same error:", "",
              "| rpict | seconds | median error | 95th pct error | mean ratio | ours s at its median error "
              "(ratio) | ours s at its 95th pct error (ratio) |", "| --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in out["rpict"]:
        if r.get("timed_out"):
            lines.append(f"| `{r['params']}` | > {r['seconds']:.0f} (stopped) | | | | | |")
            continue
        lines.append(f"| `{r['params']}` | {r['seconds']:.2f} | {100 * r['median']:.2f} % | {100 * r['p95']:.2f} % "
                     f"| {r['mean_ratio']:.4f} | {r['ours_seconds_at_equal_median']:.2f} "
                     f"({r['ours_seconds_at_equal_median'] / r['seconds']:.2f}x) | "
                     f"{r['ours_seconds_at_equal_p95']:.2f} ({r['ours_seconds_at_equal_p95'] / r['seconds']:.2f}x) |")
    lines += ["", "A ratio below 1: ours reaches rpict's error sooner. Our errors include the reference's own noise "
              "(the floor above); where an rpict error lies near that floor, the equal-error time is an upper "
              "bound."]
    return "\n".join(lines)
