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


def rpict_view(w: int, h: int) -> list[str]:
    """rpict's view options for `camera`'s eye, aim and field at w x h pixels."""
    vh = 2 * math.degrees(math.atan(math.tan(math.radians(FOV / 2)) * w / h))
    d = np.subtract(LOOK, EYE)
    return ["-vtv", "-vp", *map(str, EYE), "-vd", *map(str, d), "-vu", "0", "0", "1", "-vv", str(FOV), "-vh",
            f"{vh:.9g}"]


def rpict_luminance(pic: bytes, w: int, h: int) -> np.ndarray:
    """An rpict picture as luminance, cd/m² (h, w)."""
    import pyradiance as pr

    raw = pr.pvalue(pic, header=False, resstr=False, dataonly=True)
    rgb = np.array([float(x) for x in raw.decode().split()]).reshape(h, w, 3)
    return RADIANCE_EFFICACY * (0.265 * rgb[..., 0] + 0.670 * rgb[..., 1] + 0.065 * rgb[..., 2])


def radiance(w: int, h: int) -> tuple[dict, np.ndarray | None]:
    try:
        import pyradiance as pr
    except Exception as exc:   # an optional peer: say why it did not run
        return {"error": f"pyradiance could not be imported: {exc!r}"}, None
    with tempfile.TemporaryDirectory() as tmp:
        try:
            octree = radiance_room(Path(tmp))
            t = time.perf_counter()
            pic = pr.rpict(rpict_view(w, h), octree, xres=w, yres=h, params=RAD_PARAMS)
            seconds = time.perf_counter() - t
            lum = rpict_luminance(pic, w, h)
        except Exception as exc:
            return {"error": f"rpict failed: {exc!r}"}, None
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


CUBE_SIDE = 0.6   # m: the box the edit moves in the diffuse room


def cube(side: float) -> tuple[np.ndarray, np.ndarray]:
    """A closed cube [0, side]³ with outward normals."""
    v = side * np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
    t = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                  [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])
    return v, t


def edit_to_first_image(w: int, h: int, repeats: int = 5) -> dict:
    """The diffuse room with a 0.6 m box on the floor, through the Simulation API as the service does after a push:
    move the box (a transform change), commit the scene, build the simulation of the new revision, and render the
    first coarse image (~4 paths a pixel). Seconds from the move to the image, median of `repeats`, the kernel
    loaded."""
    from tracer.simulate import Simulation

    s, room = room_scene()
    box = s.add_instance(s.add_geometry(*cube(CUBE_SIDE)), np.eye(4))
    s.commit()
    mats = {room: {"type": "lambertian", "reflectance": RHO}, box: {"type": "lambertian", "reflectance": 0.7}}
    lights = [{"type": "point", "position": list(LIGHT), "intensity_cd": INTENSITY}]
    Simulation(s, mats, lights).run(camera(2, 2), max_photons=64)   # compile or load the kernel
    rows = []
    for i in range(repeats):
        t_move = np.eye(4)
        t_move[:3, 3] = (1.8 + 0.2 * i, 1.2 + 0.1 * i, 0.0)
        t0 = time.perf_counter()
        s.set_transform(box, t_move)
        s.commit()
        t1 = time.perf_counter()
        sim = Simulation(s, mats, lights)
        img = sim.run(camera(w, h), max_photons=4 * w * h, seed=10 + i)
        t2 = time.perf_counter()
        rows.append({"commit_s": t1 - t0, "total_s": t2 - t0, "paths": int(img.photons),
                     "median_rel": median_rel(img.luminance, img.stderr)})
    return {"width": w, "height": h, "repeats": repeats,
            "median_total_s": float(np.median([r["total_s"] for r in rows])),
            "median_commit_s": float(np.median([r["commit_s"] for r in rows])), "runs": rows}


CAR_EYE, CAR_LOOK, CAR_FOV = [9.0, -4.0, 2.5], [1.5, 0.0, 0.5], 45.0


def car_camera(w: int, h: int) -> dict:
    return {"type": "camera", "name": "car view", "position": CAR_EYE, "look_at": CAR_LOOK, "up": [0.0, 0.0, 1.0],
            "fov_deg": CAR_FOV, "width": w, "height": h}


def _car_exporter(tmpd: Path):
    """export(door_deg) -> (document, tessellation): the demo car with its doors at door_deg (degrees) written to
    STEP in tmpd and read back as the adapter reads it. Imports cadquery here, outside any timing."""
    from cad_adapter import read_document, tessellate
    from cad_adapter.samples import car_assembly
    from cad_adapter.step_uuid import write_step
    from lumenlink.demo_car import LENS_RADIUS_BEFORE_MM

    step, sidecar = tmpd / "car.step", tmpd / "car.lumenlink.json"

    def export(door_deg: float):
        built = read_document(car_assembly(door_deg, LENS_RADIUS_BEFORE_MM), sidecar=sidecar)
        write_step(built, step)
        doc = read_document(step)
        return doc, tessellate(doc)

    return export


def _render(http, sid: str, cid: str, **budget) -> tuple[float, dict]:
    """One simulation of camera cid in scene sid through REST, budget as the request's body: (wall seconds of the
    request, the answer)."""
    t0 = time.perf_counter()
    r = http.post(f"/scenes/{sid}/sensors/{cid}/simulate", json=budget)
    r.raise_for_status()
    return time.perf_counter() - t0, r.json()


def _car_size(http, sid: str, w: int, h: int, budget: float) -> tuple[str, dict]:
    """One image size of the car: its camera added, the kernel loaded (this scene's effects), the first coarse image
    (~4 paths a pixel) and a run of `budget` seconds, time to 2 % extrapolated by 1/√paths: (camera id, row)."""
    cid = http.post(f"/scenes/{sid}/sensors", json=car_camera(w, h)).json()["id"]
    load, _ = _render(http, sid, cid, max_photons=4 * w * h)   # compile or load the kernel (this scene's effects)
    first_s, first = _render(http, sid, cid, max_photons=4 * w * h, seed=1)
    run_s, r = _render(http, sid, cid, max_seconds=budget, seed=2)
    lum, err = np.asarray(r["luminance"], float), np.asarray(r["stderr"], float)
    m = median_rel(lum, err)
    return cid, {
        "width": w, "height": h, "kernel_load_seconds": load, "first_image_seconds": first_s,
        "first_image_paths": int(first["photons"]), "budget_seconds": budget, "run_seconds": run_s,
        "paths": int(r["photons"]), "median_rel": m,
        "seconds_to_2pct": run_s * (m / TARGET) ** 2 if m > TARGET else run_s,
        "light_tracing": "light tracing" in r["strategy"],
        "strategy": r["strategy"], "unreachable": r["unreachable"],
        "mean_cd_m2": float(np.mean(lum))}


def _car_edit(http, base: str, sid: str, cid: str, w: int, h: int, export) -> dict:
    """The edit-to-first-image latency: push the doors opened (a transform change; the CAD export before it not
    counted) and render camera cid's first image of the new revision (~4 paths a pixel); seconds."""
    from cad_adapter import Pusher
    from lumenlink.demo_car import DOOR_OPEN_DEG, SCENE_NAME

    doc2, tess2 = export(DOOR_OPEN_DEG)
    t0 = time.perf_counter()
    with Pusher(base) as pusher:
        pusher.push(doc2, tess2, scene=SCENE_NAME)
    push_s = time.perf_counter() - t0
    img_s, img = _render(http, sid, cid, max_photons=4 * w * h, seed=3)
    return {"width": w, "height": h, "edit": f"doors opened {DOOR_OPEN_DEG:g}°", "push_s": push_s,
            "first_image_s": img_s, "total_s": push_s + img_s, "paths": int(img["photons"])}


def demo_car(sizes: list[tuple[int, int, float]]) -> dict:
    """The demo car (`lumenlink demo`: cadquery model, STEP, the real adapter and REST API, the demo's materials and
    lights: a 5000 cd spot behind the headlamp's glass lens in a chrome housing, an IES downlight, a concrete floor)
    through the service in this process, as the page does it: per size, the first coarse image (~4 paths a pixel)
    and a run of a fixed budget (time to 2 % extrapolated by 1/√paths); then the edit-to-first-image latency: push
    the doors opened 65° (a transform change, the CAD export not counted) and render the first image of the new
    revision."""
    import httpx

    from cad_adapter import Pusher
    from lumenlink.demo import running_service
    from lumenlink.demo_car import SCENE_NAME, dress

    out: dict = {"sizes": []}
    with tempfile.TemporaryDirectory() as tmp:
        tmpd = Path(tmp)
        export = _car_exporter(tmpd)
        t = time.perf_counter()
        doc, tess = export(0.0)
        out["cad_export_s"] = time.perf_counter() - t
        with (running_service(tmpd / "var", warm_kernels=False) as base,
              httpx.Client(base_url=base, timeout=600.0) as http):
            with Pusher(base) as pusher:
                first = pusher.push(doc, tess, scene=SCENE_NAME)
            sid = first.scene_id
            uuid_of = {node.name: node.uuid for node in doc.nodes}
            dress(http, sid, uuid_of)   # the demo's materials, floor and lights
            out["effects"] = http.get(f"/scenes/{sid}").json().get("effects")
            cams = {}
            for w, h, budget in sizes:
                cams[(w, h)], row = _car_size(http, sid, w, h, budget)
                out["sizes"].append(row)
            w, h = sizes[0][:2]
            out["edit"] = _car_edit(http, base, sid, cams[(w, h)], w, h, export)
    return out


def run(quick: bool) -> dict:
    sizes = [(160, 120, 4.0)] if quick else [(160, 120, 8.0), (320, 240, 16.0)]
    cases = [case(w, h, b) for w, h, b in sizes]
    edit = edit_to_first_image(160, 120)
    try:
        car = demo_car([(160, 120, 4.0)] if quick else [(160, 120, 8.0), (320, 240, 16.0)])
    except Exception as exc:   # the car needs cadquery and the service: say why it did not run
        car = {"error": repr(exc)}
    return {"cases": cases, "edit_to_first_image": edit, "demo_car": car,
            "markdown": markdown(cases, edit, car)}


def markdown(cases: list[dict], edit: dict | None = None, car: dict | None = None) -> str:
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
    if edit:
        md += ["", f"Edit to first image, diffuse room with a {CUBE_SIDE:g} m box (Simulation API, as the service "
               f"after a push): move the box, commit, build the new revision's simulation, first {edit['width']}×"
               f"{edit['height']} image: median {edit['median_total_s']:.2f} s over {edit['repeats']} moves (commit "
               f"{1000 * edit['median_commit_s']:.1f} ms)."]
    if car:
        md += ["", "Demo car (`lumenlink demo`'s model, materials and lights, through the service in this process; "
               "light tracing runs beside the paths from the eye there: a spot behind glass in a chrome housing)."]
        if "error" in car:
            md.append(f"Did not run: {car['error']}")
        else:
            md += ["", "| image | first image s (paths) | budget run s: median error | to 2 % s | light tracing ran | "
                   "rpict |", "| --- | --- | --- | --- | --- | --- |"]
            for c in car["sizes"]:
                md.append(f"| {c['width']}×{c['height']} | {c['first_image_seconds']:.2f} "
                          f"({c['first_image_paths']:,}) | {c['run_seconds']:.1f}: {100 * c['median_rel']:.1f} % | "
                          f"{c['seconds_to_2pct']:.0f} | {'yes' if c['light_tracing'] else 'no'} | not exported "
                          f"(glass, chrome, IES downlight: no Radiance export of the car yet) |")
            e = car.get("edit")
            if e:
                md += ["", f"Car edit to first image ({e['edit']}, through REST as the page): push {e['push_s']:.2f} s "
                       f"+ first {e['width']}×{e['height']} image {e['first_image_s']:.2f} s = {e['total_s']:.2f} s "
                       f"(the CAD export, {car['cad_export_s']:.1f} s, not counted)."]
    return "\n".join(md)


if __name__ == "__main__":
    result = run(quick="--full" not in sys.argv)
    print(result["markdown"])
