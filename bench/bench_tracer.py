"""Two-level tracer benchmark: build and update times beside the paper, ray throughput beside Embree.

Sections
--------
1. The paper's three dynamic scenes (Barladyan et al. 2008, section 2), regenerated synthetically with
   the same object and triangle counts (every object a unique geometry: the worst case for a full
   build): full build (all BLAS + TLAS, JIT warm) and the commit after moving one object, beside the
   paper's 3.2 GHz Pentium IV figures. Ingest (validating and hashing the meshes in ``add_geometry``)
   is reported apart: it is not acceleration-structure work and happens once per upload.
2. Scaling of full build and move commit with the number of objects, up to 200,000.
3. Closest-hit throughput against Intel Embree (embreex, same process, same rays): a ~1M-triangle
   mesh and the 302k-triangle scene, 1M incoherent and 1M camera rays; ours on one thread and on
   two; trimesh's pure-numpy intersector on a small subset; instancing overhead (two levels against
   one flattened BVH over the same world-space triangles). The two-level scene is also traced by
   Embree with instancing (:mod:`bench.embree_instances`), the peer with the same structure.
4. Cold start: seconds to compile every kernel (empty numba cache), and to import and run once with
   the cache warm (fresh subprocesses).

Figures are medians of repeats. ``quick=True`` shrinks every size and skips the cold start.
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np

import tracer
from bench.tracer_scenes import (
    bumpy_sphere,
    camera_rays,
    embree_instanced,
    embree_scene,
    incoherent_rays,
    load_scene,
    shadow_t_max,
    synth_scene,
    world_triangles,
)

ROOT = Path(__file__).resolve().parents[1]

#: (name, objects, triangles, paper full build s, paper move commit s)
PAPER_SCENES = [
    ("scene 1 (car, fig. 3)", 19, 137_286, 7.89, "<0.01"),
    ("scene 2", 6_804, 100_215, 2.94, "0.1"),
    ("scene 3", 20_968, 302_822, 9.55, "0.25"),
]


def measure_scene(v_list, f_list, mats, repeats: int, move_repeats: int, rng) -> dict:
    """Full build (fresh scene, commit) and move-one-object commit timings."""
    builds, ingests, blas, tlas = [], [], [], []
    scene = None
    for _ in range(repeats):
        scene, ids, ingest = load_scene(v_list, f_list, mats)
        t0 = time.perf_counter()
        st = scene.commit()
        builds.append(time.perf_counter() - t0)
        ingests.append(ingest)
        blas.append(st.blas_seconds)
        tlas.append(st.tlas_seconds)
    moves, built, rebuilds, modes = [], [], [], set()
    for refit in (True, False):
        scene.tlas_refit = refit
        for _ in range(move_repeats):
            i = int(rng.integers(len(ids)))
            m = scene.instance_transform(i)
            m[:3, 3] += rng.normal(size=3) * 0.1
            scene.set_transform(i, m)
            t0 = time.perf_counter()
            st = scene.commit()
            (moves if refit else rebuilds).append(time.perf_counter() - t0)
            built.append(st.blas_built)
            if refit:
                modes.add(st.tlas_mode)
    scene.tlas_refit = True
    return {"move_rebuild_commit_s": statistics.median(rebuilds), "move_modes": sorted(modes),
            "full_build_s": statistics.median(builds), "ingest_s": statistics.median(ingests),
            "blas_s": statistics.median(blas), "tlas_s": statistics.median(tlas),
            "move_commit_s": statistics.median(moves), "move_blas_built": max(built),
            "objects": len(v_list), "triangles": int(sum(len(f) for f in f_list))}, scene


def time_trimesh(triangles_world: np.ndarray, o, d) -> float | None:
    """trimesh's pure-numpy intersector (``ray_triangle``; ``mesh.ray`` would pick Embree when present)."""
    try:
        import rtree  # noqa: F401 - ray_triangle needs it for its triangle tree
        import trimesh
        from trimesh.ray.ray_triangle import RayMeshIntersector
    except ImportError:
        return None
    mesh = trimesh.Trimesh(vertices=triangles_world.reshape(-1, 3), faces=np.arange(len(triangles_world) * 3)
                           .reshape(-1, 3), process=False)
    r = RayMeshIntersector(mesh)
    r.intersects_first(o[:10], d[:10])  # builds its r-tree outside the timing
    t0 = time.perf_counter()
    r.intersects_first(o, d)
    return len(o) / (time.perf_counter() - t0) / 1e6


def interleaved(calls: dict, repeats: int) -> tuple[dict, dict]:
    """Time each call once per round, the calls one after the other in every round (ours and the
    peers seconds apart, so a change in the shared machine's load hits all alike). Returns the
    seconds of each call in each round and each call's last result."""
    times: dict = {k: [] for k in calls}
    last: dict = {}
    for _ in range(repeats):
        for k, call in calls.items():
            t0 = time.perf_counter()
            last[k] = call()
            times[k].append(time.perf_counter() - t0)
    return times, last


def throughput(name: str, scene: tracer.Scene, rays: dict, repeats: int, tri_world: np.ndarray,
               trimesh_rays: int, instanced: bool = False) -> list[dict]:
    """Rows of the throughput table, closest hit then any hit (the same rays as shadow segments,
    :func:`shadow_t_max`); with ``instanced``, Embree also traces the scene's instances (closest hit)."""
    es = embree_scene(tri_world)
    ei = embree_instanced(scene) if instanced else None
    rows = [throughput_row(name, kind, scene, o, d, es, ei, repeats) for kind, (o, d) in rays.items()]
    for row, (o, d) in zip(rows, rays.values(), strict=True):
        if trimesh_rays:
            row["trimesh_mrays"] = time_trimesh(tri_world, o[:trimesh_rays], d[:trimesh_rays])
            row["trimesh_rays"] = trimesh_rays
    if ei is not None:
        ei[0].close()
    rng = np.random.default_rng(39)   # apart from the rays' generator: the closest-hit rays stay as they were
    diag = float(np.linalg.norm(tri_world.max((0, 1)) - tri_world.min((0, 1))))
    rows += [any_hit_row(name, kind, scene, o, d, shadow_t_max(rng, len(o), diag), es, repeats)
             for kind, (o, d) in rays.items()]
    return rows


def any_hit_row(name: str, kind: str, scene: tracer.Scene, o: np.ndarray, d: np.ndarray, t_max: np.ndarray, es,
                repeats: int) -> dict:
    """One any-hit row: ``Scene.occluded`` against Embree's ``OCCLUDED`` query (``rtcOccluded1``) on the segments
    ``o + t d``, ``0 < t < t_max``; rates and ratio as in :func:`throughput_row`."""
    o32 = np.ascontiguousarray(o, np.float32)
    d32 = np.ascontiguousarray(d, np.float32)
    t32 = np.ascontiguousarray(t_max, np.float32)
    calls = {"ours_1t": lambda: scene.occluded(o, d, t_max, threads=1),
             "ours_2t": lambda: scene.occluded(o, d, t_max, threads=2)}
    if es is not None:
        calls["embree"] = lambda: es.run(o32, d32, dists=t32, query="OCCLUDED") >= 0
    times, last = interleaved(calls, repeats)
    rate = {k: len(o) / statistics.median(ts) / 1e6 for k, ts in times.items()}
    row = {"scene": name, "rays": kind, "query": "any", "n_rays": len(o), "rounds": repeats,
           "ours_1t_mrays": rate["ours_1t"], "ours_2t_mrays": rate["ours_2t"],
           "hit_fraction": float(np.mean(last["ours_1t"]))}
    if es is not None:
        row.update(embree_1t_mrays=rate["embree"],
                   ratio_1t=statistics.median(tp / to for to, tp in zip(times["ours_1t"], times["embree"],
                                                                        strict=True)),
                   hit_agreement=float(np.mean(last["embree"] == last["ours_1t"])))
    return row


def instancing_overhead(flat: dict, two_levels: dict) -> float:
    """Speed of one flattened BVH over that of two levels, same rays. The two rows are timed minutes
    apart, each in rounds alternating with Embree's flat BVH over the same triangles; their ratios to
    it cancel a change of the machine's load between the rows (their rates alone do not)."""
    if "ratio_1t" in flat and "ratio_1t" in two_levels:
        return flat["ratio_1t"] / two_levels["ratio_1t"]
    return flat["ours_1t_mrays"] / two_levels["ours_1t_mrays"]


def throughput_row(name: str, kind: str, scene: tracer.Scene, o: np.ndarray, d: np.ndarray, es, ei,
                   repeats: int) -> dict:
    """One row: rates are medians over the rounds of :func:`interleaved`; a ratio is the median of
    the rounds' ratios."""
    o32 = np.ascontiguousarray(o, np.float32)
    d32 = np.ascontiguousarray(d, np.float32)
    calls = {"ours_1t": lambda: scene.intersect(o, d, threads=1),
             "ours_2t": lambda: scene.intersect(o, d, threads=2)}
    if es is not None:
        es.run(o32[:8], d32[:8], output=1)   # commit (BVH build) outside the timing
        calls["embree"] = lambda: es.run(o32, d32, output=1)
    if ei is not None:
        ei[0].intersect(o[:8], d[:8])   # compile the driver loop outside the timing
        calls["embree_inst"] = lambda: ei[0].intersect(o, d)
    times, last = interleaved(calls, repeats)

    def rate(k: str) -> float:
        return len(o) / statistics.median(times[k]) / 1e6

    def ratio(k: str) -> float:   # ours (one thread) / the peer, as speeds
        return statistics.median(tp / to for to, tp in zip(times["ours_1t"], times[k], strict=True))

    h = last["ours_1t"]
    row = {"scene": name, "rays": kind, "query": "closest", "n_rays": len(o), "rounds": repeats,
           "ours_1t_mrays": rate("ours_1t"),
           "ours_2t_mrays": rate("ours_2t"), "hit_fraction": float(np.mean(h.instance >= 0))}
    if es is not None:
        res = last["embree"]
        hit_e = res["geomID"] >= 0
        both = hit_e & (h.instance >= 0)
        row.update(embree_1t_mrays=rate("embree"), ratio_1t=ratio("embree"),
                   hit_agreement=float(np.mean(hit_e == (h.instance >= 0))),
                   t_max_rel_diff=float(np.max(np.abs(res["tfar"][both] - h.t[both]) / h.t[both])) if both.any()
                   else 0.0)
    if ei is not None:
        ids = ei[1][last["embree_inst"][1]]
        row.update(embree_inst_1t_mrays=rate("embree_inst"), ratio_inst_1t=ratio("embree_inst"),
                   embree_inst_build_s=ei[2], inst_agreement=float(np.mean(ids == h.instance)))
    return row


# ---------------------------------------------------------------- cold start
COLD_SCRIPT = textwrap.dedent("""
    import time, json
    t0 = time.perf_counter()
    import numpy as np, tracer
    from tracer.accel.traverse import sensor_crossings, shading_normal, hit_point
    from tracer.accel.spawn import offset_ray_origin
    t1 = time.perf_counter()
    s = tracer.Scene()
    g = s.add_geometry([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], normals=[[0, 0, 1]] * 3)
    i = s.add_instance(g, np.eye(4))
    s.add_disk_sensor([0, 0, 1], [0, 0, 1], 1.0)
    s.add_rect_sensor([0, 0, 2], [1, 0, 0], [0, 1, 0])
    s.commit()
    o = np.array([[0.2, 0.2, 5.0]]); d = np.array([[0.0, 0.0, -1.0]])
    h = s.intersect(o, d); s.occluded(o, d, 10.0)
    sa = s.arrays()
    out = [np.zeros(4, np.int64)] + [np.zeros(4) for _ in range(4)]
    sensor_crossings(sa, 0.2, 0.2, 5.0, 0.0, 0.0, -1.0, 10.0, *out)
    shading_normal(sa, 0, 0, 0.2, 0.2); hit_point(sa, 0, 0, 0.2, 0.2)
    offset_ray_origin(0.2, 0.2, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0)
    t2 = time.perf_counter()
    print(json.dumps({"import_s": t1 - t0, "first_use_s": t2 - t1}))
""")


def cold_start() -> dict:
    import json

    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache, PYTHONPATH=str(ROOT))
        runs = []
        for _ in range(3):
            t0 = time.perf_counter()
            out = subprocess.run([sys.executable, "-c", COLD_SCRIPT], env=env, capture_output=True, text=True,
                                 check=True, cwd=ROOT).stdout
            r = json.loads(out.strip().splitlines()[-1])
            r["process_s"] = time.perf_counter() - t0
            runs.append(r)
    return {"compile_all_s": runs[0]["first_use_s"], "cold_process_s": runs[0]["process_s"],
            "warm_import_s": statistics.median([r["import_s"] for r in runs[1:]]),
            "warm_first_use_s": statistics.median([r["first_use_s"] for r in runs[1:]]),
            "warm_process_s": statistics.median([r["process_s"] for r in runs[1:]])}


# ---------------------------------------------------------------- run
def _warm_up() -> None:
    v, f, m, _ = synth_scene(0, 50, 700)
    scene, _, _ = load_scene(v, f, m)
    scene.commit()
    scene.set_transform(0, m[1])
    scene.commit()
    o = np.zeros((64, 3))
    d = np.ones((64, 3))
    scene.intersect(o, d, threads=1)
    scene.intersect(o, d)


def _build_sections_from_file(out: dict) -> tuple[tracer.Scene, float]:
    """``--throughput-only``: sections 1, 2 and 4 copied into ``out`` from ``bench/results/tracer.json`` (their date
    in ``build_from``), and paper scene 3 regenerated and committed for section 3: (scene, world size in m)."""
    import json

    old = json.loads((ROOT / "bench" / "results" / "tracer.json").read_text())
    out.update(paper_scenes=old["paper_scenes"], scaling=old["scaling"], build_from=old.get("date", "?"))
    if "cold_start" in old:
        out["cold_start"] = old["cold_start"]
    v, f, m, scene3_world = synth_scene(3, *PAPER_SCENES[2][1:3])
    scene3, _, _ = load_scene(v, f, m)
    scene3.commit()
    return scene3, scene3_world


def _paper_scenes(quick: bool, rng) -> tuple[list[dict], tracer.Scene | None, float]:
    """Section 1: build and move timings of the paper's scenes (``quick``: scene 3 alone, fewer repeats), and scene 3
    as built, for section 3: (rows, scene 3, its world size in m)."""
    paper = []
    scene3 = None
    scene3_world = 0.0
    for idx, (name, n_obj, n_tri, paper_build, paper_move) in enumerate(PAPER_SCENES):
        if quick and idx < 2:
            continue
        v, f, m, world = synth_scene(idx + 1, n_obj, n_tri)
        r, scene = measure_scene(v, f, m, 1 if quick else 3, 5 if quick else 21, rng)
        r.update(name=name, paper_full_build_s=paper_build, paper_move_commit_s=paper_move)
        paper.append(r)
        if idx == 2:
            scene3, scene3_world = scene, world
    return paper, scene3, scene3_world


def _scaling(quick: bool, rng) -> list[dict]:
    """Section 2: build and move timings against the number of objects (~14.44 triangles each), up to 200,000."""
    sizes = [1_000, 5_000] if quick else [1_000, 5_000, 20_000, 50_000, 100_000, 200_000]
    scaling = []
    for n in sizes:
        v, f, m, _ = synth_scene(100 + n, n, int(n * 14.44))
        r, _ = measure_scene(v, f, m, 1 if (quick or n > 50_000) else 3, 5 if quick else 11, rng)
        scaling.append(r)
    return scaling


def _mesh_throughput(quick: bool, k: int, reps: int, tm_rays: int, rng) -> tuple[list[dict], dict]:
    """Section 3 on the bumpy sphere (1M triangles; ``quick``: 40k): its throughput rows (``k`` rays a kind) and its
    BVH build in s: (rows, ``ours_build_1m_s`` and, where embreex is there, ``embree_build_1m_s`` before it)."""
    builds = {}
    nu = 200 if quick else 1000
    v, f = bumpy_sphere(nu, nu // 2)
    big = tracer.Scene()
    big.add_instance(big.add_geometry(v, f), np.eye(4))
    t0 = time.perf_counter()
    big.commit()
    big_build = time.perf_counter() - t0
    big_rays = {"incoherent": incoherent_rays(rng, k, np.full(3, -0.7), np.full(3, 0.7)),
                "camera": camera_rays(k, np.array([0.0, -3.5, 0.5]), np.zeros(3), 40.0)}
    tri_big = v.astype(np.float32).astype(np.float64)[f]
    rows = throughput(f"mesh {len(f):,} tri", big, big_rays, reps, tri_big, tm_rays)
    t0 = time.perf_counter()
    es = embree_scene(tri_big)
    if es is not None:
        es.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32), output=1)
        builds["embree_build_1m_s"] = time.perf_counter() - t0
    builds["ours_build_1m_s"] = big_build
    return rows, builds


def _scene3_throughput(scene3: tracer.Scene, scene3_world: float, k: int, reps: int, tm_rays: int,
                       rng) -> list[dict]:
    """Section 3 on paper scene 3 (``scene3_world`` m a side): two levels against Embree flat and instanced, then
    one flattened BVH over the same world-space triangles, each of its rows with its instancing overhead."""
    tri3 = world_triangles(scene3)
    c = np.full(3, scene3_world / 2)
    s3_rays = {"incoherent": incoherent_rays(rng, k, np.zeros(3), np.full(3, scene3_world)),
               "camera": camera_rays(k, c + np.array([0.3, -1.6, 0.4]) * scene3_world, c, 50.0)}
    rows = throughput(f"paper scene 3 ({len(tri3):,} tri, 2 levels)", scene3, s3_rays, reps, tri3, tm_rays,
                      instanced=True)
    flat = tracer.Scene()
    flat.add_instance(flat.add_geometry(tri3.reshape(-1, 3), np.arange(len(tri3) * 3).reshape(-1, 3)), np.eye(4))
    flat.commit()
    flat_rows = throughput("paper scene 3, one flattened BVH", flat, s3_rays, reps, tri3, 0)
    for r2, r1 in zip(flat_rows, rows[-4:], strict=True):   # closest hit, then any hit
        r2["instancing_overhead"] = instancing_overhead(r2, r1)
    return rows + flat_rows


def run(quick: bool = False, throughput_only: bool = False, rays: int | None = None) -> dict:
    """The whole benchmark; ``throughput_only`` re-measures section 3 alone and keeps sections 1, 2 and 4 from
    ``bench/results/tracer.json`` (their date in ``build_from``); ``rays`` overrides the rays per row."""
    rng = np.random.default_rng(2008)   # one generator through sections 1-3, in this order: the same rays
    _warm_up()
    out: dict = {"quick": quick, "load_average_start": os.getloadavg(), "numba_threads": _numba_threads()}
    if throughput_only:
        scene3, scene3_world = _build_sections_from_file(out)
    else:
        out["paper_scenes"], scene3, scene3_world = _paper_scenes(quick, rng)   # 1. paper scenes
        out["scaling"] = _scaling(quick, rng)   # 2. scaling

    # 3. throughput
    k = rays or (40_000 if quick else 1_000_000)
    reps = 1 if quick else 5
    tm_rays = 200 if (quick or throughput_only) else 2_000   # trimesh takes minutes for 2,000 rays
    rows, builds = _mesh_throughput(quick, k, reps, tm_rays, rng)   # the mesh's scene freed before scene 3's rows
    out.update(builds)
    out["throughput"] = rows + _scene3_throughput(scene3, scene3_world, k, reps, tm_rays, rng)

    # 4. cold start
    if not quick and not throughput_only:
        out["cold_start"] = cold_start()
    out["load_average_end"] = os.getloadavg()
    out["markdown"] = markdown(out)
    return out


def profile_markdown() -> str | None:
    """The "Profile" subsection, from ``bench/results/tracer_profile.json`` (:mod:`bench.tracer_profile`)."""
    import json

    path = ROOT / "bench" / "results" / "tracer_profile.json"
    if not path.exists():
        return None
    from bench import tracer_profile

    return tracer_profile.markdown(json.loads(path.read_text()))


def _numba_threads() -> int:
    import numba

    return int(numba.config.NUMBA_NUM_THREADS)


def _f(x, nd=3) -> str:
    if x is None:
        return "—"
    if isinstance(x, str):
        return x
    return f"{x:.{nd}f}"


def _build_markdown(r: dict) -> list[str]:
    """Sections 1 and 2: build and move times of the paper's scenes (beside the paper's, s) and their scaling with
    the number of objects (s, µs per object, ms)."""
    lines = ["### Build and update (the paper's dynamic scenes, regenerated)", "",
             "Every object is a unique geometry. *Full build* = `commit()` of a fresh scene (all BLAS + TLAS, JIT "
             "warm); *ingest* = validating and hashing the meshes in `add_geometry`/`add_instance` (once per upload, "
             "not acceleration work); *move* = `set_transform` of one object + `commit()`. Paper: 3.2 GHz Pentium "
             "IV, 2008. Targets here: full build of 20,968 objects ≤ 0.5 s, move ≤ 5 ms. A move commit refits "
             "the top level (default policy); *TLAS rebuild* is the same move with `tlas_refit=False` (the top "
             "level rebuilt from scratch, which the default policy also does after 64 refits).", "",
             "| scene | objects | triangles | full build s (paper) | of which BLAS / TLAS s | ingest s | "
             "move commit ms (paper) | move with TLAS rebuild ms | BLAS rebuilt on move |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for p in r["paper_scenes"]:
        lines.append(f"| {p['name']} | {p['objects']:,} | {p['triangles']:,} | {_f(p['full_build_s'])} "
                     f"({p['paper_full_build_s']}) | {_f(p['blas_s'])} / {_f(p['tlas_s'])} | {_f(p['ingest_s'], 2)} | "
                     f"{_f(p['move_commit_s'] * 1e3, 2)} ({p['paper_move_commit_s']} s) | "
                     f"{_f(p['move_rebuild_commit_s'] * 1e3, 2)} | {p['move_blas_built']} |")
    lines += ["", "### Scaling with the number of objects (~14.4 triangles each)", "",
              "| objects | triangles | full build s | per object µs | move commit ms | move with TLAS rebuild ms | "
              "ingest s |",
              "| ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for s in r["scaling"]:
        n = s["objects"]
        lines.append(f"| {n:,} | {s['triangles']:,} | {_f(s['full_build_s'])} | {_f(s['full_build_s'] / n * 1e6, 1)} | "
                     f"{_f(s['move_commit_s'] * 1e3, 2)} | {_f(s['move_rebuild_commit_s'] * 1e3, 1)} | "
                     f"{_f(s['ingest_s'], 2)} |")
    return lines


def _throughput_markdown(r: dict) -> list[str]:
    """Section 3: the throughput table (Mrays/s, ratios to Embree), then where ours falls short of Embree and why,
    the instancing overhead of ours and of Embree, and the 1M-triangle BVH build (s)."""
    lines = ["", "### Closest-hit throughput (Mrays/s, same rays, same process)", "",
             "Each round times ours and the peers one after the other on the same rays; rates are medians over "
             "the rounds, a ratio (ours / Embree, one thread each) the median of the rounds' ratios. "
             "Embree via embreex (its `run` loops over rays on one thread; its BVH is built outside the timing) over "
             "the world-space triangles: one flat BVH. *Embree, 2 levels*: Embree over the same instances (one "
             "Embree scene per geometry, an instance per object with its transform; `bench/embree_instances.py`, "
             "`rtcIntersect1` per ray from a compiled loop), the peer with our structure. trimesh = "
             "`trimesh.ray.ray_triangle` (pure numpy) on a subset.", "",
             "*Any hit*: the same rays as shadow segments (`shadow_t_max`: lengths uniform up to the scene's "
             "diagonal), `Scene.occluded` (first hit found ends the walk) against Embree's `OCCLUDED` query "
             "(`rtcOccluded1`); its agreement column compares the occluded flags.", "",
             "| scene | rays | query | ours 1 thread | ours 2 threads | Embree flat, 1 thread | ratio | "
             "Embree 2 levels, 1 thread | ratio | trimesh | hit agreement |",
             "| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for t in r["throughput"]:
        lines.append(f"| {t['scene']} | {t['rays']} ({t['n_rays']:,}) | {t.get('query', 'closest')} hit | "
                     f"{_f(t['ours_1t_mrays'], 2)} | "
                     f"{_f(t['ours_2t_mrays'], 2)} | {_f(t.get('embree_1t_mrays'), 2)} | {_f(t.get('ratio_1t'), 2)} | "
                     f"{_f(t.get('embree_inst_1t_mrays'), 2)} | {_f(t.get('ratio_inst_1t'), 2)} | "
                     f"{_f(t.get('trimesh_mrays'), 4)} | {_f(t.get('hit_agreement'), 5)} |")
    short = [t for t in r["throughput"] if t.get("ratio_1t") is not None and t["ratio_1t"] < 1.0]
    if short:
        lo = min(short, key=lambda t: t["ratio_1t"])
        lines += ["", f"Short of Embree's flat BVH on one thread: {len(short)} of {len(r['throughput'])} rows, down to "
                  f"{lo['ratio_1t']:.2f} ({lo['scene']}, {lo['rays']} rays, {lo.get('query', 'closest')} hit). The "
                  "profile below says why: ours executes 2.5-4.6x Embree's instructions per ray with as many cache "
                  "misses or fewer (float64 tests of 8-bit quantised 4-wide rows and one triangle at a time, against "
                  "float32 8-wide nodes and four triangles per test). Tried against that and measured with "
                  "`bench/ab.py` (docs/ARCHITECTURE.md): eight lanes in flight (kept), packets of eight camera "
                  "rays in scenes of one mesh (kept: x0.86-0.95 time), the triangle test's setup once per ray "
                  "(kept, neutral), 8-wide float32 bottom rows (slower in the lanes), spatial splits "
                  "(`bench/results/sbvh39.json`: x0.96-0.98 for a 2.8x build), sorted ray streams "
                  "(`docs/RAYSORT.md`: x1.10 slower on incoherent rays)."]
    over = [t for t in r["throughput"] if "instancing_overhead" in t]
    if over:
        lines += ["", "Instancing overhead (one flattened BVH over the same world-space triangles vs two levels, "
                  "one thread; from each row's ratio to Embree's flat BVH, which cancels a change of load between "
                  "the rows): " + ", ".join(f"{t['rays']} {t.get('query', 'closest')} hit "
                                           f"×{t['instancing_overhead']:.2f}" for t in over) + "."]
    inst = [t for t in r["throughput"] if "embree_inst_1t_mrays" in t]
    if inst:
        lines += ["", "Embree's own instancing overhead on this scene (its flat BVH vs its two levels, one thread): "
                  + ", ".join(f"{t['rays']} ×{t['embree_1t_mrays'] / t['embree_inst_1t_mrays']:.2f}" for t in inst)
                  + f"; same instance hit by both engines for {min(t['inst_agreement'] for t in inst):.5f} of the "
                  f"rays; Embree's two-level build {inst[0]['embree_inst_build_s']:.2f} s (through ctypes, one call "
                  "per object)."]
    if "embree_build_1m_s" in r:
        lines += ["", f"BVH build of the {r['throughput'][0]['scene']}: ours {r['ours_build_1m_s']:.2f} s, "
                  f"Embree {r['embree_build_1m_s']:.2f} s (embreex default device)."]
    return lines


def markdown(r: dict) -> str:
    """The tracer section of bench/results/REPORT.md: sections 1-3, where sections 1, 2 and 4 came from, the profile
    (``bench/results/tracer_profile.json``), the cold start (s) and the machine's load."""
    lines = _build_markdown(r) + _throughput_markdown(r)
    if r.get("build_from"):
        lines += ["", f"_Build, scaling and cold start above: from the full run of {r['build_from']} (this run, "
                  "`--throughput-only`, re-measured the ray throughput only)._"]
    prof = profile_markdown()
    if prof:
        lines += ["", prof]
    if "cold_start" in r:
        c = r["cold_start"]
        lines += ["", "### Cold start", "",
                  "Compiling every tracer kernel (empty numba cache, first build + queries): "
                  f"{c['compile_all_s']:.1f} s (whole process {c['cold_process_s']:.1f} s). With the cache warm: "
                  f"import {c['warm_import_s']:.2f} s, first build + queries {c['warm_first_use_s']:.2f} s "
                  f"(whole process {c['warm_process_s']:.1f} s)."]
    lines += ["", f"_Machine load average (1 min) at start / end of this run: {r['load_average_start'][0]:.1f} / "
              f"{r['load_average_end'][0]:.1f} on {r['numba_threads']} threads; the machine was shared with other "
              "jobs, so wall times (and the 2-thread figures) are pessimistic._"]
    return "\n".join(lines)


if __name__ == "__main__":
    import json

    sys.path.insert(0, str(ROOT))   # this checkout's bench package, not an installed one

    if "--throughput-only" in sys.argv:   # section 3 only, written into tracer.json and REPORT.md as bench/run.py does
        from bench import run as bench_run

        t_start = time.perf_counter()
        n_rays = int(sys.argv[sys.argv.index("--rays") + 1]) if "--rays" in sys.argv else None
        res = run(quick="--quick" in sys.argv, throughput_only=True, rays=n_rays)
        res.update(date=time.strftime("%Y-%m-%d %H:%M:%S"), machine=bench_run.machine(),
                   wall_seconds=time.perf_counter() - t_start)
        (bench_run.RESULTS / "tracer.json").write_text(json.dumps(res, indent=2, default=float))
        from bench.tracer_profile import replace_section

        print(replace_section(bench_run.RESULTS / "REPORT.md", "tracer", res))   # the other sections as they are
        sys.exit(0)
    if "--report" in sys.argv:   # the tracer section again, with the latest profile (no measurement)
        from bench import run as bench_run
        from bench.tracer_profile import replace_section

        path = bench_run.RESULTS / "tracer.json"
        data = json.loads(path.read_text())
        data["markdown"] = markdown(data)
        path.write_text(json.dumps(data, indent=2, default=float))
        print(replace_section(bench_run.RESULTS / "REPORT.md", "tracer", data))
        sys.exit(0)
    res = run(quick="--quick" in sys.argv)
    print(res["markdown"])
    print(json.dumps({k: v for k, v in res.items() if k != "markdown"}, indent=1, default=float)[:4000])
