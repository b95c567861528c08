"""`lumenlink demo-guide` / `make demo-guide`: an edge-lit light guide as a backlight engineer builds it.

A 120 x 80 x 4 mm PMMA plate, an LED strip at its left edge (a Lambertian emitter facing the edge), a white
reflector sheet under it and a 3 x 3 illuminance grid over its lit face: what it draws is illuminance (lx) 3 mm over
the face, forward photons. It also reads the face as a display is judged: the luminance (cd/m²) a viewer in front
of it sees at the 9 points of the VESA pattern (meters 0.5 m out with a 1° cone, paths from the eye: ``POST
/scenes/{id}/luminance/uniformity``), with the uniformity min/max and its error. Its bottom face carries extraction
dots, domes 0.5 mm across, as an optical element with an inside: never meshed, prepared once into the service's
library. Two patterns side by side, two scenes of one service:

- uniform: every lattice site kept with the same probability, 0.3;
- graded: the fill grows away from the LED, from 0.27 to 0.33, as a designer grades it to make up for the light the
  dots nearer the LED have already taken out (found by hand on this guide: packing it is issue 41's job).

Then the before/after pair of issue 41 (`pack_guide`): a uniform start of fill 1.0 on an 8 x 24 map, measured,
packed (``POST /elements/{id}/pack``) against the same nine cells to min/max 0.95, the scene's assignment switched to
the result in one call, and the lit face measured again with a fresh seed; ``guide_before_after.png`` and the
pack's ``guide_pack.png``.

Everything goes through the REST API of a real service (uvicorn on loopback, SQLite in a fresh data directory).
It prints each pattern's dots, preparation time, mean illuminance and uniformity (min/max and min/mean of the nine
cells, with the cells' standard errors), and draws the maps it compares side by side on one colour scale, from the
smallest cell to the largest of them all (`compare_figure`), so a difference in uniformity shows:
``demo-output/guide_patterns.png`` (uniform, graded) and ``guide_before_after.png``.
"""

from __future__ import annotations

import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from lumenlink.demo import Narrator, running_service

SIZE = (120.0, 80.0, 4.0)     # mm
PITCH = 0.6                   # mm, the dot lattice
DOT = {"shape": "dome", "radius_mm": 0.25, "height_mm": 0.1}
EXITANCE = 2.0e6              # lm/m^2 of the LED strip's face (3 x 78 mm): 468 lm
GRID = {"type": "grid", "origin": [0.01, 0.01, 0.007], "u": [0.0, 0.06, 0.0], "v": [0.1, 0.0, 0.0], "nu": 3,
        "nv": 3, "name": "lit face (9 points)"}   # world metres, front side down, 3 mm over the top face


def fills() -> dict[str, list[list[float]]]:
    """The two patterns: fill per map column along u (= x, away from the LED), one row (the same along y)."""
    x = (np.arange(24) + 0.5) / 24
    return {"uniform": [[0.3] * 24], "graded": [list(np.round(0.27 + 0.06 * x, 4))]}


def _box(lo: tuple[float, ...], hi: tuple[float, ...]) -> tuple[np.ndarray, np.ndarray]:
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    v = np.array([[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0],
                  [x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]], np.float32)
    t = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                  [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])
    return v, t


def _quad(p0: list[float], e1: list[float], e2: list[float]) -> tuple[np.ndarray, np.ndarray]:
    p, a, b = (np.array(x, np.float32) for x in (p0, e1, e2))
    return np.array([p, p + a, p + a + b, p + b]), np.array([[0, 1, 2], [0, 2, 3]])


def _scene(ll: Any, http: Any, name: str) -> tuple[str, dict[str, str]]:
    """A scene holding the guide, the LED strip and the reflector; answers its id and the node uuids."""
    from cad_adapter.glb import encode_glb
    from tracer.geometry_id import geometry_id

    info = ll.scene(name, create=True)
    parts = {"guide": _box((0, 0, 0), SIZE),
             "led": _quad([-0.3, 1.0, 0.5], [0.0, 78.0, 0.0], [0.0, 0.0, 3.0]),   # front side +x, into the edge
             "reflector": _quad([-2.0, -2.0, -1.0], [0.0, 84.0, 0.0], [124.0, 0.0, 0.0])}   # front side up
    nodes = [{"uuid": "6c1d0000-0000-4000-8000-000000000000", "parent": None, "name": "backlight",
              "transform": list(np.eye(4).ravel()), "geometry": None}]
    for k, (part, (v, t)) in enumerate(parts.items(), start=1):
        gid = geometry_id(v, t)
        http.put(f"/geometries/{gid}", content=encode_glb(v, t), headers={"content-type": "model/gltf-binary"})
        nodes.append({"uuid": f"6c1d0000-0000-4000-8000-00000000000{k}", "parent": nodes[0]["uuid"], "name": part,
                      "transform": list(np.eye(4).ravel()), "geometry": gid})
    r = http.put(f"/scenes/{info['id']}/document", json={"base_revision": 0, "length_unit": "mm",
                                                         "nodes": nodes})
    r.raise_for_status()
    uuids = {n["name"]: n["uuid"] for n in nodes}
    ll.assign(info, "backlight/guide", {"type": "dielectric", "ior": 1.49})
    ll.assign(info, "backlight/led", {"type": "black"})
    ll.assign(info, "backlight/reflector", {"type": "lambertian", "reflectance": 0.9})
    ll.add_light(info, {"type": "area", "node": uuids["led"], "exitance_lm_m2": EXITANCE})
    return info["id"], uuids


UNIFORM_START = 1.0       # the pack's uniform start: every lattice site kept
PACK_ROWS = 8             # its map: 8 rows along y, 24 columns along x
CHECK_SEED = 20261127     # the independent check's seed (the pack's are 1009 * seed + iteration)


def compare_figure(maps: list[tuple[str, Any, Any]], grid: dict[str, Any] = GRID, title: str = "") -> Any:
    """Grid maps side by side on one colour scale (a matplotlib `Figure`, constrained layout): `maps` is
    ``[(name, lux, stderr), ...]``, each (nv, nu) lx of `grid` (rows along its v, world metres). The scale runs from
    the smallest cell of them all to the largest (not from 0: a 0.9 min/max face would look flat), one colour bar
    for all; each panel is drawn in world millimetres, x (away from the LED) across and y (along the strip) up, its
    cells written as lx ± standard error, its title its min/max ± error."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure

    from tracer.photometry.glare import uniformity

    o, u, v = (np.asarray(grid[k], float) * 1000.0 for k in ("origin", "u", "v"))
    iu, iv = int(np.argmax(np.abs(u))), int(np.argmax(np.abs(v)))
    if not (iu == 1 and iv == 0 and np.count_nonzero(u) == 1 and np.count_nonzero(v) == 1):
        raise ValueError("compare_figure draws a grid whose u runs along world y and v along world x")
    values = [np.asarray(lux, float) for _, lux, _ in maps]
    lo, hi = min(float(x.min()) for x in values), max(float(x.max()) for x in values)
    norm = Normalize(lo, hi if hi > lo else lo + 1.0)
    fig = Figure(figsize=(4.2 * len(maps) + 1.4, 4.6), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(maps), squeeze=False)[0]
    extent = (o[0], o[0] + v[0], o[1], o[1] + u[1])       # x across (the grid's v), y up (its u)
    im = None
    for ax, (name, lux, err) in zip(axes, maps, strict=True):
        e, s = np.asarray(lux, float), np.asarray(err, float)
        im = ax.imshow(e.T, origin="lower", extent=extent, cmap="inferno", norm=norm, aspect="equal",
                       interpolation="nearest")
        nv, nu = e.shape
        for (j, i), x in np.ndenumerate(e):
            ax.text(o[0] + (j + 0.5) * v[0] / nv, o[1] + (i + 0.5) * u[1] / nu, f"{x:.0f}\n± {s[j, i]:.0f}",
                    ha="center", va="center", fontsize=7, color="cyan")
        m = uniformity(e, s)
        ax.set_title(f"{name}: min/max {m['min_max']:.2f} ± {m['min_max_stderr']:.2f}", fontsize=10)
        ax.set_xlabel("x (mm), away from the LED")
        ax.set_ylabel("y (mm), along the LED strip")
    assert im is not None
    fig.colorbar(im, ax=list(axes), label=f"illuminance E (lx), {lo:.0f} to {hi:.0f}: one scale for all")
    if title:
        fig.suptitle(title, fontsize=10)
    return fig


def _save(fig: Any, path: Path) -> Path:
    fig.savefig(path, format="png")
    return path


#: the lit (top) face as the VESA 9-point figure sees it: the centres of its 3 x 3 division, world metres
NINE_POINTS = {"origin": [0.0, 0.0, SIZE[2] / 1000.0], "u": [SIZE[0] / 1000.0, 0.0, 0.0],
               "v": [0.0, SIZE[1] / 1000.0, 0.0]}


def luminance_nine(http: Any, sid: str, seed: int, max_seconds: float = 20.0) -> dict[str, Any]:
    """The luminance a viewer in front of the lit face sees at its 9 points (meters 0.5 m out, 1° cones, looking
    straight down at the face): the service's answer (``readings`` in cd/m² ± stderr, ``uniformity``)."""
    r = http.post(f"/scenes/{sid}/luminance/uniformity",
                  json={"nine_points": NINE_POINTS, "direction": [0.0, 0.0, -1.0], "distance": 0.5,
                        "aperture_deg": 1.0, "max_seconds": max_seconds, "seed": seed})
    r.raise_for_status()
    return r.json()


def say_luminance(n: Narrator, answer: dict[str, Any]) -> None:
    """The 9-point luminance and its uniformity, as a display datasheet gives them."""
    u = answer["uniformity"]
    cd = " ".join(f"{x:.0f}±{e:.0f}" for x, e in zip(answer["luminance"], answer["stderr"], strict=True))
    ud = "undefined (a reading of 0)" if u["min_max"] is None else f"{u['min_max']:.2f}" + (
        "" if u["min_max_stderr"] is None else f" ± {u['min_max_stderr']:.2f}")
    n.say(f"          luminance at the 9 points (cd/m², seen from 0.5 m, {answer['seconds']:.1f} s): {cd}; "
          f"min/max {ud}, mean {u['mean']:.0f} cd/m²" + ("" if not answer.get("unreachable") else
                                                         f"; not seen: {answer['unreachable']}"))


def _measure(http: Any, sid: str, sensor: str, photons: int, seed: int) -> dict[str, Any]:
    from tracer.photometry.glare import uniformity

    r = http.post(f"/scenes/{sid}/sensors/{sensor}/simulate", json={"max_photons": photons, "seed": seed,
                                                                      "estimator": "forward"})
    r.raise_for_status()
    a = r.json()
    u = uniformity(np.array(a["lux"]), np.array(a["stderr"]))
    return {"lux": a["lux"], "stderr": a["stderr"], "min_max": u["min_max"], "min_max_stderr": u["min_max_stderr"],
            "min_mean": u["min_mean"], "mean": u["mean"], "photons": a["photons"]}


def pack_guide(ll: Any, http: Any, out_dir: Path | None, photons: int = 400_000, target: float = 0.95,
               start_photons: int = 200_000, max_iterations: int = 10,
               progress: Any = None) -> dict[str, Any]:
    """The before/after pair: the guide with a uniform start (fill 1.0, 8 x 24 map) measured, packed to `target`
    min/max on the nine cells, switched, measured again with a fresh seed (`photons` each); answers the figures and
    the pack job's result."""
    body = {"type": "microstructure", "feature": DOT, "relief": "bump",
            "layout": {"type": "density", "origin_mm": [0.0, 0.0], "size_mm": [SIZE[0], SIZE[1]],
                       "fill": [[UNIFORM_START] * 24] * PACK_ROWS, "seed": 1, "pitch_mm": PITCH}}
    element = ll.add_element(body)
    sid, _ = _scene(ll, http, "guide-packed")
    put = ll.put_element(sid, "backlight/guide", element["id"], facing=[0, 0, -1])
    sensor = ll.add_sensor(sid, GRID)["id"]
    before = _measure(http, sid, sensor, photons, CHECK_SEED)
    t0 = time.perf_counter()
    job = ll.pack(element["id"], sid, put["id"], sensor, target=target, photons=start_photons,
                  max_photons=16 * start_photons, max_iterations=max_iterations, progress=progress)
    wall = time.perf_counter() - t0
    res = job["result"]
    if job["status"] != "succeeded" or not res or not res.get("element"):
        raise RuntimeError(f"the pack {job['status']}: {job.get('error')}")
    ll.switch_element(sid, put["id"], res["element"])
    after = _measure(http, sid, sensor, photons, CHECK_SEED + 1)
    if out_dir is not None:
        _save(compare_figure([("before (uniform start)", before["lux"], before["stderr"]),
                              ("after the pack", after["lux"], after["stderr"])],
                             title=f"the lit face before and after packing ({photons:,} photons each)"),
              out_dir / "guide_before_after.png")
        (out_dir / "guide_pack.png").write_bytes(ll.pack_png(res["element"]))
    return {"start_element": element, "before": before, "after": after, "pack": res, "pack_wall_seconds": wall,
            "target": target}


def run(out_dir: Path = Path("demo-output"), photons: int = 400_000, pack: bool = True) -> int:
    """Run the demo; 0 on success."""
    import httpx

    from lumenlink.client import Client

    n = Narrator()
    out_dir.mkdir(parents=True, exist_ok=True)
    data = Path(tempfile.mkdtemp(prefix="lumenlink-guide-"))
    try:
        with running_service(data) as url, Client(url) as ll, httpx.Client(base_url=url, timeout=600) as http:
            n.step(f"service at {url}; an edge-lit PMMA guide {SIZE[0]:g} x {SIZE[1]:g} x {SIZE[2]:g} mm, dots "
                   f"{2 * DOT['radius_mm']:g} mm across on a {PITCH:g} mm lattice under it")
            rows, sids = [], {}
            for pattern, fill in fills().items():
                body = {"type": "microstructure", "feature": DOT, "relief": "bump",
                        "layout": {"type": "density", "origin_mm": [0.0, 0.0], "size_mm": [SIZE[0], SIZE[1]],
                                   "fill": fill, "seed": 1, "pitch_mm": PITCH}}
                element = ll.add_element(body)
                sid, _ = _scene(ll, http, f"guide-{pattern}")
                sids[pattern] = sid
                put = ll.put_element(sid, "backlight/guide", element["id"], facing=[0, 0, -1])
                if not put["applied"]:
                    raise RuntimeError(f"the dots did not go onto the guide: {put['problem']}")
                sensor = ll.add_sensor(sid, GRID)["id"]
                t0 = time.perf_counter()
                r = http.post(f"/scenes/{sid}/sensors/{sensor}/simulate",
                              json={"max_photons": photons, "seed": 1, "estimator": "forward"})
                r.raise_for_status()
                answer = r.json()
                lux, err = np.array(answer["lux"]), np.array(answer["stderr"])
                rows.append((pattern, element, lux, err, time.perf_counter() - t0))
            path = _save(compare_figure([(pattern, lux, err) for pattern, _, lux, err, _ in rows],
                                        title=f"the lit face, two dot patterns ({photons:,} photons each)"),
                         out_dir / "guide_patterns.png")
            n.step("the lit face, 9 cells 33 x 20 mm, 3 mm over the guide (illuminance, forward photons)")
            nine = {pattern: luminance_nine(http, sid, seed=2) for pattern, sid in sids.items()}
            for pattern, element, lux, err, seconds in rows:
                lo, hi = int(np.argmin(lux)), int(np.argmax(lux))
                rel = np.hypot(err.ravel()[lo] / lux.ravel()[lo], err.ravel()[hi] / lux.ravel()[hi])
                n.say(f"{pattern:8s} {element['features']:6d} dots (prepared in {element['prepare_seconds']:.3f} s, "
                      f"{element['bytes']} bytes): mean {lux.mean():8.1f} lx, min/max "
                      f"{lux.min() / lux.max():.2f} ± {rel * lux.min() / lux.max():.2f}, min/mean "
                      f"{lux.min() / lux.mean():.2f}; {seconds:.1f} s; maps {path}")
                n.say("          cells (lx; rows away from the LED, columns along y): "
                      + " | ".join(" ".join(f"{x:7.1f}" for x in row) for row in lux))
                say_luminance(n, nine[pattern])
            if pack:
                n.step(f"packing the dots (issue 41): a uniform start, fill {UNIFORM_START:.1f} on an {PACK_ROWS} x 24 "
                       f"map, fed back on the nine cells to min/max 0.95")
                p = pack_guide(ll, http, out_dir, photons)
                b, a, r = p["before"], p["after"], p["pack"]
                for h in r["history"]:
                    c = h.get("confirmation")
                    again = "" if not c else (f"; a fresh seed {'confirms' if c['confirmed'] else 'does not confirm'}"
                                              f": {c['uniformity']:.3f} ± {c['stderr']:.3f}")
                    n.say(f"iteration {h['iteration']}: min/max {h['uniformity']:.3f} ± {h['stderr']:.3f} "
                          f"({h['photons']:,} photons, {h['seconds']:.1f} s; the element's update "
                          f"{h['update_seconds'] * 1000:.1f} ms{again})")
                n.say(f"before: min/max {b['min_max']:.2f} ± {b['min_max_stderr']:.2f} (min/mean {b['min_mean']:.2f}, "
                      f"mean {b['mean']:.0f} lx)")
                n.say(f"after ({r['stopped']}, {r['iterations']} iterations, {p['pack_wall_seconds']:.0f} s; checked "
                      f"with a fresh seed): min/max {a['min_max']:.2f} ± {a['min_max_stderr']:.2f} (min/mean "
                      f"{a['min_mean']:.2f}, mean {a['mean']:.0f} lx); maps "
                      f"{out_dir / 'guide_before_after.png'}, plot "
                      f"{out_dir / 'guide_pack.png'}")
        return 0
    finally:
        shutil.rmtree(data, ignore_errors=True)
