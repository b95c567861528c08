"""Accuracy against time (issue 24; docs/DESIGN.md "Accuracy is a quantity"): what each digit of accuracy costs.

(a) Photons. The diffuse room of `bench_transport` (4 × 4 × 3 m, ρ = 0.5, 1000 cd at (2, 2, 2.5)); 25 floor points
    (5 × 5 grid, disks of 5 cm). Both our estimators at doubling photon budgets: the relative error each answer
    reports (median over the points of stderr / lux) and the error measured against a long backward reference
    (RMS over the points), against the seconds spent. Beside them Radiance's `rtrace -I` on the same room
    (`bench_transport.radiance_room`) at -ab 1 … 5, other settings default: its error against its own converged
    reference (-ab 8, -ad 1024, -as 256, -aa 0.05, -ar 128, -lw 1e-5: 2.5 minutes here), and seconds (--quick:
    -ab 1, 2 against -ab 3, a smoke test). Radiance's error is a bias
    (bounces left out, ambient interpolation), which more time at a given -ab does not remove.
(b) Tessellation. A cadquery paraboloid mirror z = ρ²/4f (f = 0.25 m, rim 0.5 m, one Bézier face revolved) under a
    collimated beam (1000 lx, radius 0.45 m): every reflected photon of the true dish passes through the focus, so
    a disk of radius 0.5 mm there facing the dish receives 1000 · 0.45² / 0.0005² = 8.1e8 lx (closed form; a
    receiver as small as the blur the mesh makes, so that the error shows: a 5 cm one catches every photon from
    4 mm down). Meshed by `cad_adapter.tessellate.mesh_shape` at linear deflections 16 … 0.0625 mm (angular
    0.5 rad, so the linear one decides): the measured error |E − E₀| with its standard error, the tessellation budget
    (`error_budget.tessellation`) and the estimate (`tessellation_estimate`, issue 42: the query on the mesh split
    1→4 two or three times, extrapolated with the observed convergence) with its own seconds, each over the measured
    error, the triangles, and the seconds to mesh and to trace. `python -m bench.bench_accuracy --only
    tessellation` reruns this section alone, keeping (a) and (c) from bench/results/accuracy.json.
(c) Physics. Each effect on a scene where it matters, the same photons with and without it: Fresnel (a 5 mm pane
    of n = 1.5 glass across a beam at normal incidence against no pane; closed form (1 − R)/(1 + R) = 0.923077 of
    the beam passes), dispersion (a 60° BK7 prism at minimum deviation for the d line, a 5 mm receiver 1 m away
    along the d-line ray: Sellmeier index against the constant n_d = 1.5168, white light = 5000 K blackbody), and
    polarization (the thick plate at Brewster's angle, tests/tracer/optics/test_polarization.py, measured by the
    answer's own `physics_left_out`; closed form Rs/(1 + Rs) − 2R/(1 + R) = 0.128867 − 0.137740 of the beam).

What a digit costs: a Monte Carlo error falls as seconds^−½, so 10× less error costs 100× the seconds; the fits
below give the measured exponent and the seconds at 1 % and 0.1 %. For Radiance and the tessellation the
error-against-time slope is fitted on the measured points (log–log least squares) and stated the same way.
"""

from __future__ import annotations

import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.bench_transport import INTENSITY, LIGHT, RADIANCE_EFFICACY, RHO, floor_points, radiance_room, room_scene

RESULTS = Path(__file__).resolve().parent / "results"
RAD_REFERENCE = ["-ab", "8", "-ad", "1024", "-as", "256", "-aa", "0.05", "-ar", "128", "-lw", "1e-5"]
RAD_REFERENCE_QUICK = ["-ab", "3"]   # --quick: a smoke test of the Radiance path (-ab 1, 2 against -ab 3)
DISH_F, DISH_RIM, BEAM_R, FOCUS_R = 0.25, 0.5, 0.45, 0.0005
FOCUS_LUX = 1000.0 * BEAM_R ** 2 / FOCUS_R ** 2          # 8.1e8 lx
BK7 = {"sellmeier": {"b": [1.03961212, 0.231792344, 1.01046945], "c_um2": [0.00600069867, 0.0200179144, 103.560653]}}
N_D = 1.5168                                             # BK7 at 587.6 nm
RS_BREWSTER = 0.147929


def log(msg: str) -> None:
    print(f"bench_accuracy: {msg}", file=sys.stderr, flush=True)


def digit_cost(seconds, errors) -> dict:
    """Least-squares fit log err = a + b log s over the points; seconds per 10× less error: ×10^(−1/b), and the
    seconds the fit gives at 1 % and 0.1 % (relative errors)."""
    s, e = np.log10(np.asarray(seconds, float)), np.log10(np.asarray(errors, float))
    ok = np.isfinite(s) & np.isfinite(e)
    if ok.sum() < 2:
        return {"slope": None}
    b, a = np.polyfit(s[ok], e[ok], 1)
    out = {"slope": float(b), "points": int(ok.sum())}
    if b < 0:
        out["time_factor_per_digit"] = float(10 ** (-1 / b))
        out["seconds_at_1pct"] = float(10 ** ((-2 - a) / b))
        out["seconds_at_0.1pct"] = float(10 ** ((-3 - a) / b))
    return out


# ------------------------------------------------------------------------------------------------ (a) photons

def room_simulation():
    from tracer.simulate import Simulation

    s, room = room_scene()
    return Simulation(s, {room: {"type": "lambertian", "reflectance": RHO}},
                      [{"type": "point", "position": list(LIGHT), "intensity_cd": INTENSITY}])


def photons_curve(quick: bool) -> dict:
    sim = room_simulation()
    pts, nrm = floor_points(5)
    for est in ("backward", "forward"):   # compile (or load) outside the timings
        sim.illuminance(pts[:2], nrm[:2], max_photons=2000, estimator=est)
    log("reference (backward, long)")
    ref = sim.illuminance(pts, nrm, radius=0.05, target_relative_error=0.003 if quick else 0.001,
                          max_seconds=30.0 if quick else 150.0, seed=99, estimator="backward")
    ref_lux, ref_err = ref.lux, ref.stderr
    out = {"points": len(pts), "reference": {"estimator": "backward", "seconds": ref.seconds, "photons": ref.photons,
                                             "median_relative_stderr": float(np.median(ref_err / ref_lux)),
                                             "lux": ref_lux.tolist()}}
    budgets = {"backward": [25 * 32 * 16 * 2 ** i for i in range(0, 7 if quick else 9)],
               "forward": [160_000 * 2 ** i for i in range(0, 5 if quick else 8)]}
    for est, photon_list in budgets.items():
        rows = []
        for n in photon_list:
            r = sim.illuminance(pts, nrm, radius=0.05, max_photons=n, seed=len(rows) + 1, estimator=est)
            rel = r.stderr / r.lux
            measured = (r.lux - ref_lux) / ref_lux
            rows.append({"photons": r.photons, "seconds": r.seconds - r.compile_seconds,
                         "median_relative_stderr": float(np.median(rel)),
                         "rms_relative_stderr": float(np.sqrt(np.mean(rel ** 2))),
                         "rms_measured_error": float(np.sqrt(np.mean(measured ** 2))),
                         "rms_z": float(np.sqrt(np.mean(((r.lux - ref_lux) / np.hypot(r.stderr, ref_err)) ** 2)))})
            log(f"{est} {r.photons:,} photons {rows[-1]['seconds']:.2f} s: reported "
                f"{rows[-1]['rms_relative_stderr']:.4f}, measured {rows[-1]['rms_measured_error']:.4f}")
        out[est] = {"runs": rows,
                    "digit": digit_cost([x["seconds"] for x in rows], [x["rms_relative_stderr"] for x in rows])}
    out["radiance"] = radiance_curve(pts, quick, ref_lux)
    return out


def _rtrace(pr, rays: bytes, octree: Path, params: list[str]) -> tuple[np.ndarray, float]:
    t = time.perf_counter()
    raw = pr.rtrace(rays, octree, irradiance=True, header=False, params=params, nproc=1)
    seconds = time.perf_counter() - t
    rgb = np.array([[float(x) for x in line.split()] for line in raw.decode().strip().splitlines()])
    return RADIANCE_EFFICACY * (0.265 * rgb[:, 0] + 0.670 * rgb[:, 1] + 0.065 * rgb[:, 2]), seconds


def radiance_curve(pts: np.ndarray, quick: bool, ours: np.ndarray) -> dict:
    try:
        import pyradiance as pr
    except Exception as exc:   # an optional peer: say why it did not run
        return {"error": f"pyradiance could not be imported: {exc!r}"}
    rays = "".join(f"{p[0]:.6f} {p[1]:.6f} {1e-4:.6f} 0 0 1\n" for p in pts).encode()
    out: dict = {"runs": []}
    with tempfile.TemporaryDirectory() as d:
        try:
            octree = radiance_room(Path(d))
            params = RAD_REFERENCE_QUICK if quick else RAD_REFERENCE
            log("radiance converged reference " + " ".join(params))
            ref, ref_s = _rtrace(pr, rays, octree, params)
        except Exception as exc:
            return {"error": f"rtrace failed: {exc!r}"}
        out["reference"] = {"params": params, "seconds": ref_s, "lux": ref.tolist(),
                            "vs_ours_mean_rel": float(np.mean((ref - ours) / ours)),
                            "vs_ours_rms_rel": float(np.sqrt(np.mean(((ref - ours) / ours) ** 2)))}
        for ab in range(1, 3 if quick else 6):
            lux, s = _rtrace(pr, rays, octree, ["-ab", str(ab)])
            row = {"ab": ab, "seconds": s, "lux": lux.tolist(),
                   "rms_error_vs_own_reference": float(np.sqrt(np.mean(((lux - ref) / ref) ** 2))),
                   "rms_error_vs_ours": float(np.sqrt(np.mean(((lux - ours) / ours) ** 2)))}
            out["runs"].append(row)
            log(f"radiance -ab {ab}: {s:.2f} s, error {row['rms_error_vs_own_reference']:.4f}")
    out["digit"] = digit_cost([x["seconds"] for x in out["runs"]],
                              [x["rms_error_vs_own_reference"] for x in out["runs"]])
    return out


# ------------------------------------------------------------------------------------------------ (b) tessellation

def paraboloid_shape(f: float = DISH_F, rim: float = DISH_RIM):
    """The dish z = ρ²/4f, ρ ≤ rim, as one face: a quadratic Bézier is exactly that parabola, revolved about z."""
    import cadquery as cq
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeRevol
    from OCP.gp import gp_Ax1, gp_Dir, gp_Pnt

    edge = cq.Edge.makeBezier([cq.Vector(0, 0, 0), cq.Vector(rim / 2, 0, 0), cq.Vector(rim, 0, rim * rim / (4 * f))])
    return BRepPrimAPI_MakeRevol(edge.wrapped, gp_Ax1(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1)), 2 * math.pi).Shape()


def informs(estimate: float, error: float, value: float) -> bool:
    """Issue 42's aim for a tessellation error estimate: between the true error and 10 times it, or within 5 % of
    the value of the true error (where that is small)."""
    return error <= estimate <= 10 * error or abs(estimate - error) <= 0.05 * value


def tessellation_curve(quick: bool) -> dict:
    try:
        from cad_adapter.tessellate import mesh_shape
    except Exception as exc:
        return {"error": f"cadquery/OCP could not be imported: {exc!r}"}
    from tracer.scene import Scene
    from tracer.simulate import Simulation
    from tracer.transport.tessellation_error import from_settings

    beam = {"type": "collimated", "origin": [0, 0, 1.0], "direction": [0, 0, -1], "radius": BEAM_R,
            "illuminance_lx": 1000.0}
    linears = [0.016, 0.001, 0.00025] if quick else [0.016, 0.008, 0.004, 0.002, 0.001, 0.0005, 0.00025, 0.000125,
                                                      0.0000625]
    photons = 400_000 if quick else 1_000_000
    rows = []
    mesh_shape(paraboloid_shape(), 0.05, 0.5)   # OCCT's first call pays its own start-up: not the tolerance's cost
    for k, d in enumerate(linears):
        t = time.perf_counter()
        mesh, _ = mesh_shape(paraboloid_shape(), d, 0.5)
        mesh_s = time.perf_counter() - t
        s = Scene()
        i = s.add_instance(s.add_geometry(mesh.vertices, mesh.triangles, mesh.normals), np.eye(4))
        s.commit()
        sim = Simulation(s, {i: {"type": "mirror", "reflectance": 1.0}}, [beam])
        if k == 0:
            sim.illuminance([[0, 0, DISH_F]], [[0, 0, -1]], radius=FOCUS_R, max_photons=2000)   # compile
        r = sim.illuminance([[0, 0, DISH_F]], [[0, 0, -1]], radius=FOCUS_R, max_photons=photons, seed=k + 1,
                            tessellation_estimate=True)
        eb = r.error_budget or {}
        budget = float(eb["tessellation"][0]) if eb else 0.0
        estimate = float(eb["tessellation_estimate"][0]) if eb else 0.0
        rows.append({"linear_m": d, "angular_rad": 0.5, "triangles": int(len(mesh.triangles)),
                     "mesh_seconds": mesh_s, "trace_seconds": r.seconds - r.compile_seconds, "photons": r.photons,
                     "lux": float(r.lux[0]), "stderr": float(r.stderr[0]),
                     "error_lux": float(abs(r.lux[0] - FOCUS_LUX)), "budget_lux": budget,
                     "estimate_lux": estimate,
                     "estimate_stderr": float(eb["tessellation_estimate_stderr"][0]) if eb else 0.0,
                     "estimate_seconds": float(eb.get("tessellation_estimate_seconds", 0.0)),
                     "estimate_levels": int(eb.get("tessellation_estimate_levels", 0)),
                     "position_bound_from_settings_m": from_settings(d, 0.5, 2 * DISH_F).position})
        log(f"tessellation {d * 1000:g} mm: {len(mesh.triangles)} triangles, {r.lux[0]:.0f} ± {r.stderr[0]:.0f} lx, "
            f"budget {budget:.3g}, estimate {estimate:.3g} ({eb.get('tessellation_estimate_levels')} levels, "
            f"{eb.get('tessellation_estimate_seconds', 0.0):.1f} s)")
    resolved = [x for x in rows if x["error_lux"] > 3 * x["stderr"]]
    first, last = resolved[0], resolved[-1]
    digits = math.log10(first["error_lux"] / last["error_lux"]) if len(resolved) > 1 else 0.0
    t_first = first["mesh_seconds"] + first["trace_seconds"]
    t_last = last["mesh_seconds"] + last["trace_seconds"]
    return {"closed_form_lux": FOCUS_LUX, "receiver_radius_m": FOCUS_R, "photons": photons, "runs": rows,
            "budget_holds": all(x["budget_lux"] + 4 * x["stderr"] >= x["error_lux"] for x in rows),
            "estimate_informs": all(informs(x["estimate_lux"], x["error_lux"], FOCUS_LUX) for x in rows),
            "digit": {"from_linear_m": first["linear_m"], "to_linear_m": last["linear_m"], "digits": digits,
                      "seconds_from": t_first, "seconds_to": t_last,
                      "triangles_from": first["triangles"], "triangles_to": last["triangles"],
                      "time_factor_per_digit": (t_last / t_first) ** (1 / digits) if digits > 0 else None,
                      "triangle_factor_per_digit": ((last["triangles"] / first["triangles"]) ** (1 / digits)
                                                    if digits > 0 else None)},
            "triangles_vs_linear": digit_cost([x["linear_m"] for x in rows], [x["triangles"] for x in rows])}


# ------------------------------------------------------------------------------------------------ (c) physics

def _pair(sim_on, sim_off, pts, nrm, radius, photons) -> dict:
    """The same query with the effect (sim_on) and without (sim_off), compiled first, timed after."""
    for sim in (sim_on, sim_off):
        sim.illuminance(pts, nrm, radius=radius, max_photons=2000, estimator="forward")
    on = sim_on.illuminance(pts, nrm, radius=radius, max_photons=photons, seed=1, estimator="forward")
    off = sim_off.illuminance(pts, nrm, radius=radius, max_photons=photons, seed=2, estimator="forward")
    return {"lux_with": float(on.lux[0]), "stderr_with": float(on.stderr[0]), "seconds_with": on.seconds,
            "lux_without": float(off.lux[0]), "stderr_without": float(off.stderr[0]), "seconds_without": off.seconds,
            "difference": float(on.lux[0] - off.lux[0]), "difference_stderr": float(math.hypot(on.stderr[0],
                                                                                                 off.stderr[0])),
            "effects_with": on.effects, "effects_without": off.effects, "photons": on.photons}


def physics_effects(quick: bool) -> dict:
    from tracer.scene import Scene
    from tracer.simulate import Simulation
    from tracer.warmup import box

    photons = 200_000 if quick else 1_000_000
    out = {}
    # Fresnel: a pane across a 100 lx beam at normal incidence, against no pane
    beam = {"type": "collimated", "origin": [0, 0, 0.5], "direction": [0, 0, -1], "radius": 0.2,
            "illuminance_lx": 100.0}
    s = Scene()
    pane = s.add_instance(s.add_geometry(*box([-1, -1, 0.0], [1, 1, 0.005])), np.eye(4))
    s.commit()
    empty = Scene()
    empty.add_instance(empty.add_geometry(*box([5, 5, 5], [6, 6, 6])), np.eye(4))   # far away: nothing in the beam
    empty.commit()
    pts, nrm = [[0.0, 0.0, -0.2]], [[0.0, 0.0, 1.0]]
    log("physics: Fresnel pane")
    row = _pair(Simulation(s, {pane: {"type": "dielectric", "ior": 1.5}}, [beam]),
                Simulation(empty, {}, [beam], default_material={"type": "black"}), pts, nrm, 0.15, photons)
    r = 0.04
    row["closed_form_difference"] = 100.0 * ((1 - r) / (1 + r) - 1)
    out["fresnel"] = {"scene": "5 mm pane of n = 1.5 across a 100 lx beam at normal incidence, against no pane",
                      **row}
    # dispersion: a BK7 prism at minimum deviation for n_d
    a, length = 0.05, 0.05
    h = a * math.sqrt(3) / 2
    v = np.array([[-a / 2, -length / 2, 0], [a / 2, -length / 2, 0], [0, -length / 2, h],
                  [-a / 2, length / 2, 0], [a / 2, length / 2, 0], [0, length / 2, h]], float)
    tri = np.array([[0, 1, 2], [3, 5, 4], [0, 4, 1], [0, 3, 4], [1, 5, 2], [1, 4, 5], [2, 3, 0], [2, 5, 3]])  # outward
    ps = Scene()
    prism = ps.add_instance(ps.add_geometry(v, tri), np.eye(4))
    ps.commit()
    i = math.asin(N_D * 0.5)
    n_in, t_face = np.array([0.866025403784, 0.0, -0.5]), np.array([0.5, 0.0, 0.866025403784])
    d_in = math.cos(i) * n_in + math.sin(i) * t_face
    d_out = d_in * np.array([1.0, 1.0, -1.0])
    entry, exit_ = np.array([-a / 4, 0.0, h / 2]), np.array([a / 4, 0.0, h / 2])
    white = {"type": "blackbody", "kelvin": 5000}
    light = [{"type": "collimated", "origin": list(entry - 0.2 * d_in), "direction": list(d_in), "radius": 0.002,
              "illuminance_lx": 1000.0, "spectrum": white}]
    target = exit_ + 1.0 * d_out
    log("physics: BK7 prism")
    row = _pair(Simulation(ps, {prism: {"type": "dielectric", "ior": BK7}}, light),
                Simulation(ps, {prism: {"type": "dielectric", "ior": N_D}}, light), [list(target)], [list(-d_out)],
                0.005, photons)
    out["dispersion"] = {"scene": "60° BK7 prism, 2 mm beam of 5000 K light at minimum deviation for n_d, 5 mm "
                                  "receiver 1 m away on the d-line ray: Sellmeier against constant n_d = 1.5168", **row}
    # polarization: the thick plate at Brewster, through the answer's own physics_left_out
    log("physics: thick plate at Brewster (physics_left_out)")
    ts = Scene()
    glass = ts.add_instance(ts.add_geometry(*box([-5, -5, -0.01], [5, 5, 0])), np.eye(4))
    ts.commit()
    t = math.atan(1.5)
    d = np.array([math.sin(t), 0.0, -math.cos(t)])
    sim = Simulation(ts, {glass: {"type": "dielectric", "ior": 1.5}},
                     [{"type": "collimated", "origin": list(-d), "direction": list(d), "radius": 0.005,
                       "illuminance_lx": 100.0}])
    refl = d * np.array([1, 1, -1])
    off = {"force_effects_off": ["polarization"]}   # on by default since issue 38: measure the s/p average's gap
    sim.illuminance([list(refl)], [list(-refl)], radius=0.3, max_photons=2000, physics_left_out=["polarization"], **off)
    res = sim.illuminance([list(refl)], [list(-refl)], radius=0.3, max_photons=photons, seed=1,
                          physics_left_out=["polarization"], **off)
    e = res.physics_left_out["polarization"]
    scale = 100.0 * 0.005 ** 2 / 0.3 ** 2
    out["polarization"] = {
        "scene": "1 cm lossless plate (n = 1.5) at Brewster's angle, 5 mm beam of 100 lx, 0.3 m receiver across "
                 "the reflection; the answer's physics_left_out",
        "lux_with": float(res.lux[0] + e["difference"][0]), "stderr_with": float(e["stderr"][0]),
        "seconds_with": e["seconds"], "lux_without": float(res.lux[0]), "stderr_without": float(res.stderr[0]),
        "seconds_without": res.seconds, "difference": float(e["difference"][0]),
        "difference_stderr": float(e["stderr"][0]), "effects_with": [*res.effects, "polarization"],
        "effects_without": res.effects, "photons": res.photons,
        "closed_form_difference": scale * (RS_BREWSTER / (1 + RS_BREWSTER) - RS_BREWSTER / (1 + RS_BREWSTER / 2))}
    for row in out.values():
        row["relative_difference"] = row["difference"] / row["lux_without"] if row["lux_without"] else None
        row["time_ratio"] = row["seconds_with"] / row["seconds_without"]
        if "closed_form_difference" in row:
            row["z_vs_closed_form"] = (row["difference"] - row["closed_form_difference"]) / row["difference_stderr"]
    return out


# ------------------------------------------------------------------------------------------------ plots, report

def _save_figure(plt, fig, name: str) -> str:
    """Lay the figure out, write bench/results/<name> at 110 dpi, close it: returns the name (the report lists it)."""
    fig.tight_layout()
    fig.savefig(RESULTS / name, dpi=110)
    plt.close(fig)
    return name


def _plot_photons(plt, a: dict) -> str:
    """(a): relative error (RMS over the floor points) against seconds, log–log: each estimator's reported and
    measured error, Radiance's -ab runs against its converged one, and the floor set by our reference's own error."""
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for est, colour in (("backward", "tab:blue"), ("forward", "tab:orange")):
        rows = a[est]["runs"]
        s = [x["seconds"] for x in rows]
        ax.loglog(s, [x["rms_relative_stderr"] for x in rows], "o-", color=colour, label=f"LumenLink {est}: reported")
        ax.loglog(s, [x["rms_measured_error"] for x in rows], "x--", color=colour,
                  label=f"LumenLink {est}: measured vs reference")
    rad = a["radiance"]
    if "runs" in rad:
        s = [x["seconds"] for x in rad["runs"]]
        ax.loglog(s, [x["rms_error_vs_own_reference"] for x in rad["runs"]], "s-", color="tab:green",
                  label="Radiance rtrace -I, -ab 1…5 (vs its converged run)")
        for x in rad["runs"]:
            ax.annotate(f"-ab {x['ab']}", (x["seconds"], x["rms_error_vs_own_reference"]), fontsize=7)
    ref = a["reference"]["median_relative_stderr"]
    ax.axhline(ref, color="grey", lw=0.8, ls=":", label=f"our reference's own error ({ref:.2%})")
    ax.set_xlabel("seconds")
    ax.set_ylabel("relative error (RMS over 25 floor points)")
    ax.set_title("Diffuse room: error against time")
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
    return _save_figure(plt, fig, "accuracy_photons.png")


def _plot_tessellation(plt, t: dict) -> str | None:
    """(b): lux error at the focus (measured ±2σ, budget, estimate, stderr) and the seconds to mesh and to trace,
    against the linear deflection in mm; None where the section did not run."""
    if "runs" not in t:
        return None
    rows = t["runs"]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4.2))
    d = [x["linear_m"] * 1000 for x in rows]
    ax1.errorbar(d, [x["error_lux"] for x in rows], yerr=[2 * x["stderr"] for x in rows], fmt="o-",
                 label=f"|E − {FOCUS_LUX:.3g} lx| measured (±2σ)")
    ax1.loglog(d, [x["budget_lux"] for x in rows], "s--", label="tessellation budget (answer)")
    ax1.loglog(d, [max(x.get("estimate_lux", 0.0), 1e-3) for x in rows], "^:",
               label="tessellation estimate (refined mesh)")
    ax1.loglog(d, [x["stderr"] for x in rows], ":", color="grey", label="Monte Carlo stderr")
    ax1.set_xscale("log")
    ax1.set_yscale("log")
    ax1.set_xlabel("linear deflection, mm")
    ax1.set_ylabel("lux at the focus")
    ax1.set_title("Paraboloid mirror: error against tolerance")
    ax1.legend(fontsize=7)
    ax1.grid(True, which="both", alpha=0.3)
    ax2.loglog(d, [x["mesh_seconds"] for x in rows], "o-", label="mesh (OCCT)")
    ax2.loglog(d, [x["trace_seconds"] for x in rows], "s-", label=f"trace ({t['photons']:,} photons)")
    ax2.set_xlabel("linear deflection, mm")
    ax2.set_ylabel("seconds")
    ax2.set_title("and its time")
    ax2.legend(fontsize=7)
    ax2.grid(True, which="both", alpha=0.3)
    return _save_figure(plt, fig, "accuracy_tessellation.png")


def plots(res: dict) -> list[str]:
    """The three figures of the report, written to bench/results/: their file names, (a), (b) where it ran, (c)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [_plot_photons(plt, res["photons"])]
    if tessellation := _plot_tessellation(plt, res["tessellation"]):
        names.append(tessellation)
    # (c): what each effect changes (% of the lux without it, ±2σ) and what it costs (seconds without and with)
    p = res["physics"]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    keys = list(p)
    rel = [100 * (p[k]["relative_difference"] or 0.0) for k in keys]
    err = [100 * p[k]["difference_stderr"] / p[k]["lux_without"] if p[k]["lux_without"] else 0 for k in keys]
    ax1.bar(keys, rel, yerr=[2 * e for e in err], color="tab:purple")
    ax1.axhline(0, color="k", lw=0.8)
    ax1.set_ylabel("lux with − without, % of without (±2σ)")
    ax1.set_title("What each effect changes")
    x = np.arange(len(keys))
    ax2.bar(x - 0.2, [p[k]["seconds_without"] for k in keys], 0.4, label="without")
    ax2.bar(x + 0.2, [p[k]["seconds_with"] for k in keys], 0.4, label="with")
    ax2.set_xticks(x, keys)
    ax2.set_ylabel(f"seconds ({p[keys[0]]['photons']:,} photons)")
    ax2.set_title("and what it costs")
    ax2.legend(fontsize=8)
    names.append(_save_figure(plt, fig, "accuracy_physics.png"))
    return names


def _digit_text(dc: dict) -> str:
    if dc.get("slope") is None:
        return "too few points to fit"
    if "time_factor_per_digit" not in dc:
        return f"error does not fall with time (slope {dc['slope']:+.2f})"
    return (f"error ∝ seconds^{dc['slope']:.2f}: each 10× less error costs ×{dc['time_factor_per_digit']:,.0f} the "
            f"seconds (fit: 1 % at {dc['seconds_at_1pct']:.3g} s, 0.1 % at {dc['seconds_at_0.1pct']:.3g} s)")


def _photons_markdown(a: dict) -> list[str]:
    """Section (a): the relative errors (RMS over the floor points) and seconds of each run, ours and Radiance's,
    and what a digit of accuracy costs each."""
    md = [f"### (a) Diffuse room, {a['points']} floor points: relative error against seconds", "",
          f"Reference: backward, {a['reference']['photons']:,} paths in {a['reference']['seconds']:.1f} s, median "
          f"relative stderr {a['reference']['median_relative_stderr']:.2%}.", "",
          "| method | budget | seconds | reported error (RMS) | measured error vs reference (RMS) | RMS z |",
          "| --- | ---: | ---: | ---: | ---: | ---: |"]
    for est in ("backward", "forward"):
        for x in a[est]["runs"]:
            md.append(f"| LumenLink {est} | {x['photons']:,} | {x['seconds']:.2f} | {x['rms_relative_stderr']:.3%} | "
                      f"{x['rms_measured_error']:.3%} | {x['rms_z']:.2f} |")
    rad = a["radiance"]
    if "runs" in rad:
        for x in rad["runs"]:
            md.append(f"| Radiance rtrace -I -ab {x['ab']} | — | {x['seconds']:.2f} | none given | "
                      f"{x['rms_error_vs_own_reference']:.3%} vs its converged run ({x['rms_error_vs_ours']:.2%} vs "
                      f"ours) | — |")
        r = rad["reference"]
        md += ["", f"Radiance's converged run ({' '.join(r['params'])}) took {r['seconds']:.1f} s and lies "
                   f"{r['vs_ours_mean_rel']:+.2%} from our reference on average (RMS {r['vs_ours_rms_rel']:.2%}): "
                   "the two programs' models of the room (a 1 cm light sphere against a point, plastic against "
                   "Lambertian) agree to that."]
    else:
        md += ["", f"Radiance did not run: {rad.get('error')}"]
    md += ["", "What a digit costs:", "",
           f"- LumenLink backward: {_digit_text(a['backward']['digit'])};",
           f"- LumenLink forward: {_digit_text(a['forward']['digit'])};"]
    if "digit" in rad:
        md.append(f"- Radiance -ab 1…5: {_digit_text(rad['digit'])}. Its error is a bias: it falls with bounces, "
                  "not with time spent at one setting, and the answer does not say how large it is.")
    return md + ["", "RMS z near 1 means the reported standard errors are the real ones (measured against the "
                     "reference, whose own error is included).", ""]


def _tessellation_markdown(t: dict) -> list[str]:
    """Section (b): per linear deflection the lux error at the focus beside the budget and the estimate, and what a
    digit costs in seconds and triangles; or why it did not run."""
    md = ["### (b) Paraboloid mirror: lux error against tessellation tolerance", ""]
    if "runs" not in t:
        return md + [f"Did not run: {t.get('error')}"]
    md += [f"Focus of a cadquery paraboloid (f = {DISH_F} m, rim {DISH_RIM} m) under a collimated beam; closed "
           f"form {FOCUS_LUX:.3g} lx on a disk of radius {FOCUS_R * 1000:g} mm at the focus; {t['photons']:,} "
           "photons per run; angular deflection 0.5 rad.", "",
           "| linear deflection | triangles | mesh s | trace s | lux ± stderr | error | budget | budget / error "
           "| estimate ± stderr | estimate / error | estimate s (splits) |",
           "| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for x in t["runs"]:
        ratio = x["budget_lux"] / x["error_lux"] if x["error_lux"] > 0 else math.inf
        est = x.get("estimate_lux", 0.0)
        est_ratio = est / x["error_lux"] if x["error_lux"] > 0 else math.inf
        mark = "" if informs(est, x["error_lux"], FOCUS_LUX) else " ✗"
        md.append(f"| {x['linear_m'] * 1000:g} mm | {x['triangles']:,} | {x['mesh_seconds']:.2f} | "
                  f"{x['trace_seconds']:.2f} | {x['lux']:.4g} ± {x['stderr']:.2g} | "
                  f"{x['error_lux'] / FOCUS_LUX:.2%} | "
                  f"{x['budget_lux']:.3g} | {ratio:,.3g}× | {est:.3g} ± {x.get('estimate_stderr', 0.0):.2g} | "
                  f"{est_ratio:,.3g}×{mark} | {x.get('estimate_seconds', 0.0):.2f} "
                  f"({x.get('estimate_levels', 0)}) |")
    dg, tv = t["digit"], t["triangles_vs_linear"]
    loosest = min(x["budget_lux"] / x["error_lux"] for x in t["runs"] if x["error_lux"] > 0)
    return md + [
        "", f"Triangles ∝ deflection^{tv.get('slope') or float('nan'):.2f}. The error is the share of the "
            "photons the facets send past the small receiver, so it falls slowly while the blur is wider than "
            "the receiver and then abruptly. From "
            f"{dg['from_linear_m'] * 1000:g} mm to {dg['to_linear_m'] * 1000:g} mm (the finest whose error "
            f"exceeds 3σ) it fell by {dg['digits']:.1f} digits while mesh + trace went from "
            f"{dg['seconds_from']:.2f} s to {dg['seconds_to']:.2f} s: "
            + (f"×{dg['time_factor_per_digit']:.2f} the seconds and ×{dg['triangle_factor_per_digit']:.1f} "
               "the triangles per digit" if dg["time_factor_per_digit"] else "no digit resolved")
            + " — tessellation digits are cheap next to photon digits (×100 each): the tracing time grows "
            "little with the triangles (a BVH), so a fine tolerance costs mostly meshing and memory.",
        "", "The tessellation budget " + ("bounds the measured error at every setting" if t["budget_holds"]
                                          else "does NOT bound the measured error everywhere")
        + f" (budget / error ≥ {loosest:,.3g}): it is a bound built for receivers larger than the photons' "
        "shift (the first-order normal term; `tracer.transport.tessellation_error`), and on a 0.5 mm disk "
        "at a focus "
        "it says little more than \"the tessellation may move everything\".",
        "", "The estimate (`\"tessellation_estimate\": true`) "
        + ("lies between the error and 10× it, or within 5 % of the value of it, at every setting"
           if t.get("estimate_informs") else "misses issue 42's aim where marked ✗ (between the error and 10× "
           "it, or within 5 % of the value of it)")
        + ": the same query on the mesh split 1→4 two or three times (`tracer.transport.tessellation_error."
        "refine`: new vertices on a quartic fitted to the positions and normals around each edge), "
        "extrapolated with the observed convergence ratio r ≤ ½ and Roache's factor 1.25; its seconds are "
        "those it added to the query (the refinements and 2–3 more runs)."]


def markdown(res: dict) -> str:
    """The accuracy section of bench/results/REPORT.md: sections (a) and (b) from their helpers, then (c), the lux
    each effect left out changes and its seconds."""
    md = ["Three accuracy-time curves (issue 24): photons, tessellation tolerance, physics left out. Plots: "
          "`accuracy_photons.png`, `accuracy_tessellation.png`, `accuracy_physics.png`.", "",
          *_photons_markdown(res["photons"]), *_tessellation_markdown(res["tessellation"])]
    p = res["physics"]
    md += ["", "### (c) Physics left out: lux difference and time with and without each effect", "",
           "| effect | scene | lux without | lux with | difference ± stderr | \\|difference\\| / σ | closed form "
           "| z vs closed form | seconds without → with |",
           "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for k, x in p.items():
        cf = f"{x['closed_form_difference']:.4g}" if "closed_form_difference" in x else "—"
        z = f"{x['z_vs_closed_form']:+.1f}" if "z_vs_closed_form" in x else "—"
        md.append(f"| {k} | {x['scene']} | {x['lux_without']:.4g} ± {x['stderr_without']:.2g} | {x['lux_with']:.4g} "
                  f"± {x['stderr_with']:.2g} | {x['difference']:+.4g} ± {x['difference_stderr']:.2g} "
                  f"({100 * (x['relative_difference'] or 0):+.1f} %) | "
                  f"{abs(x['difference']) / x['difference_stderr']:.1f} "
                  f"| {cf} | {z} | {x['seconds_without']:.2f} → "
                  f"{x['seconds_with']:.2f} (×{x['time_ratio']:.2f}) |")
    sig = [abs(x["difference"]) / x["difference_stderr"] for x in p.values() if x["difference_stderr"] > 0]
    md += ["", f"Leaving an effect out moves these values by {min(sig):.0f} to {max(sig):.0f} standard errors of the "
               "difference: an error beside the Monte Carlo one that no number of photons removes. A query measures it "
               "itself with `\"physics_left_out\": [\"polarization\"]` (the polarization row is that answer: a "
               "second run with the effect forced on, same budget, independent seed)."]
    return "\n".join(md)


def run(quick: bool) -> dict:
    import numba

    res: dict = {"threads": numba.config.NUMBA_NUM_THREADS}
    t0 = time.perf_counter()
    log("(a) photons: the diffuse room, both estimators and Radiance")
    res["photons"] = photons_curve(quick)
    log(f"(b) tessellation: the paraboloid dish ({time.perf_counter() - t0:.0f} s so far)")
    res["tessellation"] = tessellation_curve(quick)
    log(f"(c) physics ({time.perf_counter() - t0:.0f} s so far)")
    res["physics"] = physics_effects(quick)
    RESULTS.mkdir(parents=True, exist_ok=True)
    res["plots"] = plots(res)
    res["markdown"] = markdown(res)
    return res


def rerun_tessellation(quick: bool) -> dict:
    """Section (b) alone: the other sections from bench/results/accuracy.json, then that file and REPORT.md
    rewritten (`bench.run.write_report`)."""
    import json

    from bench.run import machine, write_report

    path = RESULTS / "accuracy.json"
    res = json.loads(path.read_text())
    t0 = time.perf_counter()
    res["tessellation"] = tessellation_curve(quick)
    res["plots"] = plots(res)
    res["markdown"] = markdown(res)
    res.update(date=time.strftime("%Y-%m-%d %H:%M:%S"), machine=machine(), quick=quick,
               tessellation_wall_seconds=time.perf_counter() - t0)
    path.write_text(json.dumps(res, indent=2, default=float))
    write_report()
    return res


if __name__ == "__main__":
    import json

    if "--only" in sys.argv and sys.argv[sys.argv.index("--only") + 1] == "tessellation":
        print(json.dumps(rerun_tessellation(quick="--quick" in sys.argv)["tessellation"], indent=1,
                         default=float)[:3000])
    else:
        print(json.dumps(run(quick="--quick" in sys.argv), indent=1, default=float)[:3000])
