"""What ``bench/bench_gpu.py``'s four sections measure (closest hit beside Mitsuba 3 / OptiX, commit after a move,
photons, first-use compile) and the sizes they run at. A module of its own so that each stays under the house's 600
lines: bench_gpu.py finds the device, runs these sections in order, and writes the results file and the report."""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tarfile
import tempfile
import textwrap
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
MITSUBA_ENV = "LUMENLINK_MITSUBA"
MITSUBA_VARIANT = "cuda_ad_rgb"
#: a time-to-target query longer than this is run once, not repeated
LONG_RUN_S = 5.0


@dataclass(frozen=True)
class Sizes:
    """What a run traces; ``FULL`` on a GPU, ``QUICK`` where a run must be short, ``SMOKE`` in the simulator."""

    ray_counts: tuple[int, ...]
    repeats: int
    scene3: tuple[int, int]          # objects, triangles
    mesh: tuple[int, int]            # bumpy_sphere(nu, nv): 2 nu nv triangles
    moves: int
    room_points: int                 # n × n floor points for the time to 1 %
    target: float                    # relative error of the time-to-target rows
    max_seconds: float               # budget of one time-to-target query
    rate_seconds: float              # one photons/s run lasts about this long
    min_photons: int
    max_photons: int
    cold_compile: bool               # the compile child gets an empty numba cache


FULL = Sizes((1_000_000, 16_000_000), 5, (20_968, 302_822), (1000, 500), 21, 10, 0.01, 30.0, 1.0,
             1_000_000, 256_000_000, True)
QUICK = replace(FULL, ray_counts=(1_000_000,), moves=11, max_seconds=20.0, rate_seconds=0.5)
# the simulator runs each thread in Python: few rays and rounds (5 rounds of 256 made the smoke test 90 s, issue 49)
SMOKE = Sizes((32, 128), 2, (40, 600), (16, 8), 3, 2, 0.05, 5.0, 0.05, 2_000, 20_000, False)


def log(msg: str) -> None:
    """A timestamped progress line on stderr, apart from the report printed on stdout."""
    print(f"bench_gpu [{time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def median(xs) -> float:
    """The median of timings or rates as a plain float (for the JSON)."""
    return float(statistics.median(xs))


def cpu_threads() -> int:
    """The threads numba runs our CPU kernels on: the CPU columns' core count."""
    import numba

    return int(numba.get_num_threads())


# ---------------------------------------------------------------- scenes and rays
@dataclass
class Case:
    key: str            # scene3 or mesh
    name: str
    scene: object       # tracer.Scene, committed
    vertices: np.ndarray  # flattened world-space triangles for the peer: (n, 3) float32 vertices, (m, 3) faces
    faces: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    eye: np.ndarray
    target: np.ndarray
    fov: float


def build_cases(sizes: Sizes) -> list[Case]:
    """Scene 3 (two levels) and the bumpy sphere, with the ray boxes and cameras of ``bench/instructions.py``."""
    import tracer
    from bench.tracer_scenes import bumpy_sphere, load_scene, synth_scene, world_triangles

    cases = []
    n_obj, n_tri = sizes.scene3
    v, f, m, world = synth_scene(3, n_obj, n_tri)
    s3, _, _ = load_scene(v, f, m)
    s3.commit()
    tri = world_triangles(s3).astype(np.float32)
    c = np.full(3, world / 2)
    cases.append(Case("scene3", f"paper scene 3 ({n_obj:,} objects, {len(tri):,} tri, 2 levels)", s3,
                      tri.reshape(-1, 3), np.arange(len(tri) * 3, dtype=np.uint32).reshape(-1, 3), np.zeros(3),
                      np.full(3, world), c + np.array([0.3, -1.6, 0.4]) * world, c, 50.0))
    nu, nv = sizes.mesh
    v, f = bumpy_sphere(nu, nv)
    mesh = tracer.Scene()
    mesh.add_instance(mesh.add_geometry(v, f), np.eye(4))
    mesh.commit()
    cases.append(Case("mesh", f"mesh {len(f):,} tri", mesh, v.astype(np.float32), f.astype(np.uint32),
                      np.full(3, -0.7), np.full(3, 0.7), np.array([0.0, -3.5, 0.5]), np.zeros(3), 40.0))
    return cases


def make_rays(case: Case, kind: str, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The rays of ``bench/instructions.py`` (same seed, same boxes and cameras) at count ``n``."""
    from bench.tracer_scenes import camera_rays, incoherent_rays

    if kind == "incoherent":
        o, d = incoherent_rays(np.random.default_rng(1), n, case.lo, case.hi)
    else:
        o, d = camera_rays(n, case.eye, case.target, case.fov)
    return np.ascontiguousarray(o), np.ascontiguousarray(d)


# ---------------------------------------------------------------- ours on the GPU
def gpu_calls(ds, o: np.ndarray, d: np.ndarray) -> tuple[dict, Callable]:
    """Our closest-hit kernel over rays already on the card, one call = launch to device sync; and what it found
    (read after the rounds): ``({"gpu": call}, read)``."""
    from tracer.gpu.traverse import THREADS, closest_kernel, cuda

    k = len(o)
    do, dd, dtm = cuda.to_device(o), cuda.to_device(d), cuda.to_device(np.full(k, np.inf))
    outs = (cuda.device_array(k, np.float64), cuda.device_array(k, np.int64), cuda.device_array(k, np.int64),
            cuda.device_array(k, np.float64), cuda.device_array(k, np.float64), cuda.device_array((k, 3), np.float64))
    sa = ds._kernel_arrays()   # the device arrays (in the simulator, what they hold: see DeviceScene)
    grid = (k + THREADS - 1) // THREADS

    def launch() -> None:
        closest_kernel[grid, THREADS](sa, do, dd, dtm, *outs)
        cuda.synchronize()

    def read() -> dict:
        return {"t": outs[0].copy_to_host(), "instance": outs[1].copy_to_host(), "primitive": outs[2].copy_to_host()}

    launch()   # compiled before (warm_gpu); this loads it and touches the rays
    return {"gpu": launch}, read


def warm_gpu(case: Case):
    """The case's scene on the device, both kernels compiled (first use, outside every timing)."""
    from tracer.gpu.traverse import DeviceScene

    ds = DeviceScene(case.scene.arrays())
    o, d = make_rays(case, "camera", 64)
    ds.intersect(o, d)
    ds.occluded(o, d)
    return ds


# ---------------------------------------------------------------- Mitsuba 3 (OptiX) on the same card
class Mitsuba:
    """Mitsuba 3 from the packed wheels (a directory to put on sys.path, or the .tar.xz that
    ``shared/tools/pack-mitsuba-cuda`` writes, unpacked here into a temporary directory); ``skipped`` says why not."""

    def __init__(self, path: str | None, variant: str = MITSUBA_VARIANT):
        self.variant = variant
        self.skipped: str | None = None
        self.version: str | None = None
        self._tmp: tempfile.TemporaryDirectory | None = None
        if not path:
            self.skipped = (f"no packed Mitsuba given (--mitsuba PATH or {MITSUBA_ENV}; "
                            "shared/tools/pack-mitsuba-cuda makes one)")
            return
        p = Path(path)
        if not p.exists():
            self.skipped = f"packed Mitsuba not found at {path}"
            return
        try:
            if p.is_file():
                self._tmp = tempfile.TemporaryDirectory(prefix="lumenlink-mitsuba-")
                with tarfile.open(p) as tar:
                    tar.extractall(self._tmp.name, filter="data")
                p = Path(self._tmp.name)
            sys.path.insert(0, str(p))
            import drjit as dr
            import mitsuba as mi

            mi.set_variant(variant)
            self.mi, self.dr = mi, dr
            self.version = f"mitsuba {mi.__version__}, drjit {dr.__version__}"
        except Exception as exc:   # noqa: BLE001 - any failure to load the peer skips its column, saying why
            self.skipped = f"Mitsuba {variant} did not load: {type(exc).__name__}: {exc}"

    def scene(self, vertices: np.ndarray, faces: np.ndarray):
        """A Mitsuba scene of one mesh: float32 world-space vertices (n, 3), uint32 faces (m, 3)."""
        mi = self.mi
        mesh = mi.Mesh("flattened", len(vertices), len(faces), has_vertex_normals=False,
                       has_vertex_texcoords=False)
        params = mi.traverse(mesh)
        params["vertex_positions"] = mi.Float(np.ascontiguousarray(vertices, np.float32).ravel())
        params["faces"] = mi.UInt32(np.ascontiguousarray(faces, np.uint32).ravel())
        params.update()
        return mi.load_dict({"type": "scene", "mesh": mesh})

    def calls(self, scene, o: np.ndarray, d: np.ndarray) -> tuple[dict, Callable]:
        """``ray_intersect`` (t, primitive, uv and normal evaluated) and ``ray_intersect_preliminary`` over rays
        already on the card, one call = evaluated and synchronised, both warm; and the t of the last full call."""
        mi, dr = self.mi, self.dr

        def vec(cls, a):
            return cls(*(mi.Float(np.ascontiguousarray(a[:, j], np.float32)) for j in range(3)))

        ray = mi.Ray3f(vec(mi.Point3f, o), vec(mi.Vector3f, d))
        dr.eval(ray)
        dr.sync_thread()
        last: dict = {}

        def full() -> None:
            si = scene.ray_intersect(ray)
            dr.eval(si.t, si.prim_index, si.uv, si.n)
            dr.sync_thread()
            last["t"] = si.t

        def preliminary() -> None:
            pi = scene.ray_intersect_preliminary(ray)
            dr.eval(pi.t, pi.prim_index, pi.prim_uv)
            dr.sync_thread()

        def read() -> np.ndarray:
            return np.asarray(last["t"], np.float64)

        for call in (full, full, preliminary, preliminary):   # the first traces and compiles, the second runs cached
            call()
        return {"optix": full, "optix_prelim": preliminary}, read


# ---------------------------------------------------------------- section 1: rays
def ray_row(case: Case, kind: str, o: np.ndarray, d: np.ndarray, ds, mscene, peer: Mitsuba, repeats: int) -> dict:
    """One row. Each round times ours on the GPU, Mitsuba's two calls and ours on the CPU one after the other on the
    same rays (`bench.bench_tracer.interleaved`); rates are medians over the rounds, a ratio the median of the
    rounds' ratios. Then ``DeviceScene.intersect`` end to end, host arrays in and out."""
    from bench.bench_tracer import interleaved

    k = len(o)
    calls, read_gpu = gpu_calls(ds, o, d)
    read_peer = None
    if mscene is not None and peer.skipped is None:
        try:
            more, read_peer = peer.calls(mscene, o, d)
            calls.update(more)
        except Exception as exc:   # noqa: BLE001 - the peer failing skips its columns, saying why
            peer.skipped = f"Mitsuba ray_intersect failed: {type(exc).__name__}: {exc}"
    hits: dict = {}
    case.scene.intersect(o[:64], d[:64])
    calls["cpu"] = lambda: hits.update(h=case.scene.intersect(o, d))
    times, _ = interleaved(calls, repeats)
    end_to_end, _ = interleaved({"gpu_end_to_end": lambda: ds.intersect(o, d)}, repeats)
    times.update(end_to_end)

    def rate(key: str) -> float | None:
        return k / median(times[key]) / 1e6 if key in times else None

    def ratio(key: str) -> float | None:   # ours on the GPU / the other, as speeds
        return median(tk / tg for tg, tk in zip(times["gpu"], times[key], strict=True)) if key in times else None

    g, h = read_gpu(), hits["h"]
    same = (g["instance"] == h.instance) & (g["primitive"] == h.primitive)
    both = (h.instance >= 0) & (g["instance"] >= 0)
    row = {"scene": case.name, "scene_key": case.key, "rays": kind, "n_rays": k,
           "gpu_mrays": rate("gpu"), "optix_mrays": rate("optix"), "cpu_mrays": rate("cpu"),
           "cpu_threads": cpu_threads(), "gpu_end_to_end_mrays": rate("gpu_end_to_end"),
           "optix_preliminary_mrays": rate("optix_prelim"), "gpu_over_optix": ratio("optix"),
           "gpu_over_cpu": ratio("cpu"), "rounds": repeats, "hit_fraction": float(np.mean(h.instance >= 0)),
           "gpu_cpu_same_hit": float(np.mean(same)),
           "gpu_cpu_t_max_rel_diff": float(np.max(np.abs(g["t"][both] - h.t[both]) / h.t[both])) if both.any()
           else 0.0}
    if read_peer is not None:
        hit = np.isfinite(read_peer())
        row.update(optix_hit_fraction=float(np.mean(hit)),
                   optix_cpu_hit_agreement=float(np.mean(hit == (h.instance >= 0))))
        peer.dr.flush_malloc_cache()
    return row


def ray_rows(cases: list[Case], sizes: Sizes, peer: Mitsuba) -> tuple[list[dict], dict]:
    rows = []
    builds: dict = {}
    for case in cases:
        t0 = time.perf_counter()
        ds = warm_gpu(case)
        builds[case.key] = {"gpu_first_upload_and_compile_s": time.perf_counter() - t0,
                            "gpu_bytes": int(ds.uploaded_bytes)}
        mscene = None
        if peer.skipped is None:
            try:
                t0 = time.perf_counter()
                mscene = peer.scene(case.vertices, case.faces)
                builds[case.key]["optix_build_s"] = time.perf_counter() - t0
            except Exception as exc:   # noqa: BLE001
                peer.skipped = f"Mitsuba scene did not build: {type(exc).__name__}: {exc}"
        for kind in ("incoherent", "camera"):
            for n in sizes.ray_counts:
                o, d = make_rays(case, kind, n)
                log(f"rays: {case.key} {kind} {len(o):,}")
                rows.append(ray_row(case, kind, o, d, ds, mscene, peer, sizes.repeats))
    return rows, builds


# ---------------------------------------------------------------- section 2: commit after a move
def commit_after_move(case: Case, sizes: Sizes) -> dict:
    """Move one object (a random one each time), commit, upload the revision; medians over ``sizes.moves``."""
    from tracer.gpu.traverse import DeviceScene, cuda

    scene = case.scene
    ids = list(scene.instances())
    ds = DeviceScene(scene.arrays())
    rng = np.random.default_rng(27)
    commits, uploads, totals, fields, nbytes, blas = [], [], [], set(), [], 0
    for step in range(sizes.moves + 1):   # the first move compiles the refit: not counted
        i = ids[int(rng.integers(len(ids)))]
        m = scene.instance_transform(i)
        m[:3, 3] += rng.normal(size=3) * 0.1
        scene.set_transform(i, m)
        t0 = time.perf_counter()
        st = scene.commit()
        t1 = time.perf_counter()
        sent = ds.update(scene.arrays())
        cuda.synchronize()
        t2 = time.perf_counter()
        if step:
            commits.append(t1 - t0)
            uploads.append(t2 - t1)
            totals.append(t2 - t0)
            fields.update(sent)
            nbytes.append(ds.uploaded_bytes)
            blas = max(blas, st.blas_built)
    return {"scene": case.name, "objects": len(ids), "moves": sizes.moves, "commit_s": median(commits),
            "upload_s": median(uploads), "commit_and_upload_s": median(totals), "max_commit_and_upload_s": max(totals),
            "uploaded_fields": sorted(fields), "uploaded_bytes": int(median(nbytes)), "blas_built": int(blas)}


# ---------------------------------------------------------------- section 3: photons
def _room(backend=None):
    from bench.bench_transport import INTENSITY, LIGHT, RHO, room_scene
    from tracer.simulate import Simulation

    s, room = room_scene()
    return Simulation(s, {room: {"type": "lambertian", "reflectance": RHO}},
                      [{"type": "point", "position": list(LIGHT), "intensity_cd": INTENSITY}], backend=backend)


def cuda_backend():
    """``tracer.gpu.backend.CudaBackend()``, or the reason it cannot be had."""
    try:
        from tracer.gpu.backend import CudaBackend
    except ImportError as exc:
        return None, f"tracer.gpu.backend.CudaBackend is not built yet ({exc})"
    try:
        return CudaBackend(), ""
    except Exception as exc:   # noqa: BLE001
        return None, f"CudaBackend() failed: {type(exc).__name__}: {exc}"


def photon_rate(sim, sizes: Sizes) -> dict:
    """Forward photons/s at 9 floor points: a run sized to last about ``sizes.rate_seconds``, median of repeats."""
    from bench.bench_transport import floor_points

    pts, nrm = floor_points(3)
    sim.illuminance(pts, nrm, max_photons=1000, estimator="forward")   # compile or load the kernel
    probe = sim.illuminance(pts, nrm, max_photons=sizes.min_photons, seed=1, estimator="forward")
    rate = probe.photons / max(probe.seconds, 1e-9)
    photons = int(min(sizes.max_photons, max(sizes.min_photons, rate * sizes.rate_seconds)))
    rates, lux = [], None
    for rep in range(sizes.repeats):
        r = sim.illuminance(pts, nrm, max_photons=photons, seed=2 + rep, estimator="forward")
        rates.append(r.photons / r.seconds)
        lux = r.lux
    return {"photons": photons, "photons_per_second": median(rates), "lux_mean": float(np.mean(lux)),
            "backend": r.backend}


def time_to_target(sim, sizes: Sizes, estimator: str, repeats: int) -> dict:
    """Seconds to the target relative error (worst point) at n × n floor points, warm; median of ``repeats`` runs
    (of one where the first took over `LONG_RUN_S`: a device call lasts 10 minutes at most)."""
    from bench.bench_transport import floor_points

    pts, nrm = floor_points(sizes.room_points)
    sim.illuminance(pts[:2], nrm[:2], max_photons=2000, estimator=estimator)   # compile or load the kernel
    runs = []
    for rep in range(repeats):
        runs.append(sim.illuminance(pts, nrm, radius=0.05, target_relative_error=sizes.target,
                                    max_seconds=sizes.max_seconds, seed=1 + rep, estimator=estimator))
        if runs[0].seconds > LONG_RUN_S:
            break
    repeats = len(runs)
    last = runs[-1]
    return {"estimator": estimator, "points": len(pts), "target_relative_error": sizes.target,
            "seconds": median([r.seconds for r in runs]), "runs": repeats,
            "photons": int(median([r.photons for r in runs])), "stop_reason": last.stop_reason,
            "worst_relative_error": float(np.max(last.stderr / last.lux)), "lux": last.lux.tolist(),
            "stderr": last.stderr.tolist(), "backend": last.backend}


def photons_section(sizes: Sizes) -> dict:
    out: dict = {"cpu_threads": cpu_threads()}
    backend, why = cuda_backend()
    out["gpu_skipped"] = why or None
    log("photons: CPU, all cores")
    cpu = _room()
    out["cpu"] = {"rate": photon_rate(cpu, sizes),
                  "to_target": {"backward": time_to_target(cpu, sizes, "backward", sizes.repeats),
                                "forward": time_to_target(cpu, sizes, "forward", 1)}}
    if backend is not None:
        log("photons: GPU (CudaBackend)")
        gpu = None
        try:
            gpu = _room(backend)
            out["gpu"] = {"rate": photon_rate(gpu, sizes), "to_target": {}}
        except Exception as exc:   # noqa: BLE001 - a backend still being built: say what failed, keep the rest
            out["gpu_skipped"] = f"forward photons on CudaBackend failed: {type(exc).__name__}: {exc}"
        if "gpu" in out:
            for est in ("backward", "forward"):
                try:
                    out["gpu"]["to_target"][est] = time_to_target(gpu, sizes, est, sizes.repeats)
                except Exception as exc:   # noqa: BLE001
                    out["gpu"]["to_target"][est] = {"skipped": f"{type(exc).__name__}: {exc}"}
            for est, g in out["gpu"]["to_target"].items():
                c = out["cpu"]["to_target"][est]
                if "lux" in g:
                    sd = np.hypot(np.asarray(g["stderr"]), np.asarray(c["stderr"]))
                    g["max_abs_z_vs_cpu"] = float(np.max(np.abs(np.asarray(g["lux"]) - np.asarray(c["lux"]))
                                                         / np.where(sd > 0, sd, np.inf)))
        if hasattr(backend, "close"):
            backend.close()
    return out


# ---------------------------------------------------------------- section 4: first-use compile
COMPILE_SCRIPT = textwrap.dedent("""
    import json, sys, time
    sys.path.insert(0, {root!r})
    t0 = time.perf_counter()
    import numpy as np
    import tracer
    from tracer.gpu.traverse import DeviceScene, cuda
    t1 = time.perf_counter()
    s = tracer.Scene()
    g = s.add_geometry([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    s.add_instance(g, np.eye(4))
    s.commit()
    o = np.array([[0.2, 0.2, 5.0]]); d = np.array([[0.0, 0.0, -1.0]])
    s.intersect(o, d); s.occluded(o, d, 10.0)
    t2 = time.perf_counter()
    ds = DeviceScene(s.arrays())
    ds.intersect(o, d); cuda.synchronize()
    t3 = time.perf_counter()
    ds.occluded(o, d, 10.0); cuda.synchronize()
    t4 = time.perf_counter()
    out = {{"import_s": t1 - t0, "cpu_first_use_s": t2 - t1, "closest_kernel_s": t3 - t2, "any_kernel_s": t4 - t3}}
    try:
        from tracer.gpu.backend import CudaBackend
    except ImportError as exc:
        out["photons_skipped"] = f"tracer.gpu.backend.CudaBackend is not built yet ({{exc}})"
    else:
        try:
            import bench.gpu_sections as b
            sim = b._room(CudaBackend())
            t5 = time.perf_counter()
            r = sim.illuminance([[2.0, 2.0, 0.0]], [[0.0, 0.0, 1.0]], max_photons=1000, estimator="forward")
            out["forward_photons_first_use_s"] = time.perf_counter() - t5
            out["forward_compile_seconds"] = float(r.compile_seconds)
        except Exception as exc:
            out["photons_skipped"] = f"{{type(exc).__name__}}: {{exc}}"
    print(json.dumps(out))
""")


def compile_section(sizes: Sizes, cache_dir: str | None = None) -> dict:
    """Two children on one numba cache directory: the first finds it empty (``cold_compile``; in the smoke run the
    default cache instead, to stay short), the second finds what the first left. ``cache_dir``: this process's own
    cache (:func:`share_cache_with_children`), used where it is still empty."""
    script = COMPILE_SCRIPT.format(root=str(ROOT))
    out: dict = {"cold_cache": sizes.cold_compile}
    with tempfile.TemporaryDirectory(prefix="lumenlink-numba-") as fresh:
        cache = cache_dir if cache_dir and not any(Path(cache_dir).iterdir()) else fresh
        env = dict(os.environ, PYTHONPATH=str(ROOT))
        if sizes.cold_compile:
            env["NUMBA_CACHE_DIR"] = cache
        for label in ("first", "second"):
            log(f"compile: {label} child process")
            t0 = time.perf_counter()
            r = subprocess.run([sys.executable, "-c", script], env=env, cwd=ROOT, capture_output=True, text=True,
                               timeout=1200)
            if r.returncode:
                out[label] = {"error": r.stderr[-2000:]}
                continue
            out[label] = json.loads(r.stdout.strip().splitlines()[-1])
            out[label]["process_s"] = time.perf_counter() - t0
    return out
