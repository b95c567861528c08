"""Bit-identical answers across a refactor: record every field of every query kind on fixed seeds, then compare.

    python -m bench.answers_snapshot record before.pkl      # on the old tree
    python -m bench.answers_snapshot record after.pkl       # on the new tree
    python -m bench.answers_snapshot compare before.pkl after.pkl   # "identical", or which fields differ

The queries: points forward and backward, observe spectrum and Stokes, a "lit" target scope, a grid with both
estimators, a surface, a far field, and physics_left_out on points and on a grid (a glass room, so that the
polarization pilot runs), and luminance (paths from the eye, `tracer.transport.radiance`): a meter and a camera
in a room lit by an area light with a mirror wall, a camera on a caustic of a point light in a mirror (light
tracing) and on a floor under a collimated beam; each feature shape of an element in each layout it takes; and a glass
block with each inside and surface a dielectric takes (in the forms both older and newer trees read: the medium's
fields on the dielectric, the kind `rough_dielectric`). Seconds, compile seconds and cost (which depend on the machine)
are left out; every other field is compared with np.array_equal (NaN equal to NaN). Used for issue 35's moves
(docs/guides/benchmarks.md).
"""

from __future__ import annotations

import pickle
import sys

import numpy as np

TIMED = ("seconds", "compile_seconds", "cost")


def fields_of(res) -> dict:
    out = {}
    for k, v in vars(res).items():
        if k in TIMED:
            continue
        if k == "physics_left_out" and isinstance(v, dict):
            v = {n: {kk: vv for kk, vv in e.items() if kk != "seconds"} for n, e in v.items()}
        out[k] = v
    return out


def record(path: str) -> None:
    from tests.tracer.transport_scenes import box, scene_of
    from tracer.simulate import Simulation

    s, ids = scene_of(box([-2, -2, 0], [2, 2, 2.5]))
    light = {"type": "point", "position": [0.2, -0.1, 2.0], "intensity_cd": 1000.0}
    sim = Simulation(s, {ids[0]: {"type": "lambertian", "reflectance": 0.5}}, [light])
    p = np.array([[0.0, 0.0, 0.0], [1.0, 0.3, 0.0], [-0.6, 1.1, 0.0]])
    n = np.tile([0.0, 0.0, 1.0], (3, 1))
    grid = ([-1.5, -1.5, 0], [3, 0, 0], [0, 3, 0])
    out = {}
    for est in ("forward", "backward"):
        out["points_" + est] = fields_of(sim.illuminance(p, n, radius=0.3, max_photons=20000, seed=1, estimator=est))
    out["observe"] = fields_of(sim.illuminance(p, n, radius=0.3, max_photons=20000, seed=2, estimator="forward",
                                               observe=["spectrum", "stokes"]))
    out["target_lit"] = fields_of(sim.illuminance(p, n, radius=0.3, target_relative_error=0.05, seed=3,
                                                  target_scope="lit"))
    out["grid"] = fields_of(sim.grid(*grid, 4, 3, max_photons=20000, seed=4))
    out["grid_backward"] = fields_of(sim.grid(*grid, 4, 3, max_photons=2000, seed=4, estimator="backward"))
    out["surface"] = fields_of(sim.surface([ids[0]], max_photons=20000, seed=5))
    out["far_field"] = fields_of(sim.far_field(8, 5, max_photons=20000, seed=6))
    glass = Simulation(s, {ids[0]: {"type": "dielectric", "ior": 1.5}}, [light])
    out["left_out"] = fields_of(glass.illuminance(p, n, radius=0.3, max_photons=20000, seed=7,
                                                  physics_left_out=["polarization"]))
    out["grid_left_out"] = fields_of(glass.grid([-1.5, -1.5, 0.1], [3, 0, 0], [0, 3, 0], 2, 2, max_photons=20000,
                                                seed=8, physics_left_out=["polarization"]))
    out.update(luminance_queries())
    out.update(element_queries())
    out.update(medium_queries())
    with open(path, "wb") as f:
        pickle.dump(out, f)
    print(f"recorded {len(out)} queries to {path}")


def luminance_queries() -> dict:
    """Paths from the eye with each light capability: an area light (MIS), a point light seen in a mirror (light
    tracing of a caustic), a collimated beam (light tracing always)."""
    from tests.tracer.transport_scenes import quad, scene_of
    from tracer.simulate import Simulation

    s, ids = scene_of(quad([0, -5, 0], [10, 0, 0], [0, 10, 0]), quad([0, -5, 0], [0, 10, 0], [0, 0, 5]),
                      quad([2, -0.5, 3], [0, 1, 0], [1, 0, 0]))   # floor (+z), mirror (+x), panel facing down
    floor, mirror, panel = ({"type": "lambertian", "reflectance": 0.7}, {"type": "mirror", "reflectance": 0.9},
                            {"type": "lambertian", "reflectance": 0.2})
    mats = dict(zip(ids, (floor, mirror, panel), strict=True))
    camera = {"type": "camera", "position": [3.0, 0.0, 2.5], "look_at": [2.0, 0.0, 0.0], "fov_deg": 30.0,
              "width": 6, "height": 4}
    meter = {"type": "luminance", "position": [1.5, 0.0, 1.5], "direction": [0.0, 0.0, -1.0], "aperture_deg": 10.0}
    area = Simulation(s, mats, [{"type": "area", "instances": [ids[2]], "exitance_lm_m2": 5000.0}])
    point = Simulation(s, mats, [{"type": "point", "position": [0.5, 0.0, 1.0], "intensity_cd": 300.0}])
    beam = Simulation(s, mats, [{"type": "collimated", "origin": [3.0, 0.0, 2.0], "direction": [0.0, 0.0, -1.0],
                                 "width": 1.0, "height": 1.0, "illuminance_lx": 1000.0}])
    return {"lum_area_meter": fields_of(area.run(meter, max_photons=4000, seed=11)),
            "lum_area_camera": fields_of(area.run(camera, max_photons=8000, seed=12)),
            "lum_point_camera": fields_of(point.run(camera, max_photons=8000, seed=13)),
            "lum_beam_camera": fields_of(beam.run(camera, max_photons=8000, seed=14))}


def element_queries() -> dict:
    """Each feature shape on a PMMA plate under a slanted beam, with each layout it takes: the grid below it."""
    import math

    from tests.tracer.transport_scenes import box
    from tracer.elements import prepare
    from tracer.scene import Scene
    from tracer.simulate import Simulation

    features = {"dome": {"shape": "dome", "radius_mm": 0.08, "height_mm": 0.04},
                "pyramid": {"shape": "pyramid", "base_mm": 0.15, "height_mm": 0.05},
                "prism": {"shape": "prism", "base_mm": 0.1, "apex_deg": 90},
                "corner_cube": {"shape": "corner_cube", "side_mm": 0.15}}
    layouts = {"grid": {"type": "grid", "pitch_mm": [0.2, 0.2]}, "hex": {"type": "hex", "pitch_mm": 0.2},
               "density": {"type": "density", "origin_mm": [0, 0], "size_mm": [4, 4], "fill": [[0.2, 0.5], [0.8, 0.4]],
                           "pitch_mm": 0.2},
               "points": {"type": "points", "uv_mm": [[0.5 + 0.3 * i, 0.4 + 0.25 * j] for i in range(10)
                                                      for j in range(12)]}}
    takes = {"dome": layouts, "corner_cube": layouts, "pyramid": ("grid", "density", "points"), "prism": ("grid",)}
    s30 = math.sin(math.radians(30))
    beam = {"type": "collimated", "origin": [2e-3 - 2e-3 * s30, 2e-3, 3e-3], "radius": 1.5e-3,
            "direction": [s30, 0, -math.cos(math.radians(30))], "illuminance_lx": 1000.0}
    out = {}
    for shape, feature in features.items():
        for k, name in enumerate(takes[shape]):
            scene = Scene()
            v, t = box([0, 0, 0], [4e-3, 4e-3, 1e-3])
            part = scene.add_instance(scene.add_geometry(v, t), np.eye(4))
            for relief, facing in (("bump", [0, 0, -1]), ("pit", [0, 0, 1]))[k % 2:k % 2 + 1]:
                element = prepare({"type": "microstructure", "feature": feature, "layout": layouts[name],
                                   "relief": relief})
                scene.set_element(part, element, facing=facing)
            scene.commit()
            sim = Simulation(scene, {part: {"type": "dielectric", "ior": 1.49}}, [beam])
            out[f"element_{shape}_{name}"] = fields_of(sim.grid([-1e-3, -1e-3, -1e-3], [6e-3, 0, 0], [0, 6e-3, 0],
                                                                 4, 4, max_photons=20000, seed=21, estimator="forward"))
    return out


def medium_queries() -> dict:
    """A glass block in a room, with each inside and surface a dielectric takes: absorbing and scattering
    (Henyey–Greenstein), Mie particles, fluorescent, rough, rough and brushed, coated; points under the block."""
    from tests.tracer.transport_scenes import box, scene_of
    from tracer.simulate import Simulation

    s, (room, block) = scene_of(box([-2, -2, 0], [2, 2, 2.5]), box([-0.5, -0.5, 0.5], [0.5, 0.5, 1.0]))
    light = {"type": "point", "position": [0.1, 0.05, 2.0], "intensity_cd": 1000.0}
    white = {"type": "lambertian", "reflectance": 0.5}
    insides = {"hg": {"absorption_per_m": 0.8, "scattering_per_m": 3.0, "g": 0.6},
               "mie": {"particles": {"radius_um": 0.5, "ior": [1.59, 0.0], "number_per_m3": 1e15}},
               "fluorescent": {"fluorescence": {"absorption_per_m": 50.0, "quantum_yield": 0.8,
                                                "emission": {"type": "monochromatic", "nm": 600.0}}},
               "rough": {"alpha": 0.2}, "brushed": {"alpha": 0.05, "alpha_y": 0.3, "axis": [1.0, 0.0, 0.0]},
               "coated": {"coating": {"layers": [{"ior": 1.38, "thickness_nm": 99.6}]}}}
    p = np.array([[0.0, 0.0, 0.0], [0.3, 0.2, 0.0], [1.2, -0.4, 0.0]])
    n = np.tile([0.0, 0.0, 1.0], (3, 1))
    out = {}
    for k, (name, inside) in enumerate(insides.items()):
        glass = {"type": "rough_dielectric" if "alpha" in inside else "dielectric", "ior": 1.5, **inside}
        sim = Simulation(s, {room: white, block: glass}, [light])
        out[f"medium_{name}"] = fields_of(sim.illuminance(p, n, radius=0.3, max_photons=20000, seed=31 + k,
                                                          estimator="forward"))
    return out


def same(x, y) -> bool:
    if isinstance(x, dict):
        return isinstance(y, dict) and x.keys() == y.keys() and all(same(x[k], y[k]) for k in x)
    if isinstance(x, list | tuple):
        return isinstance(y, list | tuple) and len(x) == len(y) and all(same(p, q) for p, q in zip(x, y, strict=True))
    if isinstance(x, np.ndarray):
        return isinstance(y, np.ndarray) and x.shape == y.shape and np.array_equal(x, y, equal_nan=True)
    return x == y


def compare(a_path: str, b_path: str) -> int:
    with open(a_path, "rb") as fa, open(b_path, "rb") as fb:
        a, b = pickle.load(fa), pickle.load(fb)
    bad = {k: sorted(f for f in a[k] if not same(a[k][f], b.get(k, {}).get(f))) for k in a if not same(a[k], b.get(k))}
    if not bad and a.keys() == b.keys():
        print("identical")
        return 0
    print(f"differ: {bad or sorted(set(a) ^ set(b))}")
    return 1


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "record":
        record(sys.argv[2])
    elif len(sys.argv) == 4 and sys.argv[1] == "compare":
        sys.exit(compare(sys.argv[2], sys.argv[3]))
    else:
        sys.exit(__doc__)
