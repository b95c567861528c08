"""The tracer on a CUDA GPU (issue 27) beside Mitsuba 3 / OptiX on the same card and our CPU on all its cores.

Sections
--------
1. Closest hit, Mrays/s: the paper's scene 3 (20,968 objects, 302,822 triangles, two levels) and the 1M-triangle
   bumpy sphere, incoherent and camera rays (the rays of ``bench/instructions.py``), 1M and 16M rays. Ours on the GPU
   (:class:`tracer.gpu.traverse.DeviceScene`'s closest-hit kernel over rays already on the card: the kernel launch
   timed to a device synchronisation, warm, median of the repeats; also end to end through
   ``DeviceScene.intersect``, host arrays in and out); Mitsuba 3 ``cuda_ad_rgb`` (OptiX's own traversal) on the same
   card and the same rays (``ray_intersect`` on the flattened scene; imported from the packed wheels of
   ``shared/tools/pack-mitsuba-cuda``, ``--mitsuba PATH`` or ``LUMENLINK_MITSUBA``; the column is skipped, with the
   reason, where it is absent); our CPU on all its cores (``Scene.intersect``, ``cpu_threads``).
2. Photons: forward photons/s in the diffuse room of ``bench/bench_transport.py`` and the time to 1 % at 100 floor
   points, through ``tracer.simulate.Simulation(..., backend=CudaBackend())`` where ``tracer.gpu.backend`` has it
   (rows skipped with the reason where not), beside the CPU on all its cores.
3. Commit after moving one object of scene 3, the upload of the new revision included (``DeviceScene.update``
   sends only the instances and top levels on a move).
4. First-use compile seconds of the GPU kernels, in a child process with an empty numba cache in a temporary
   directory, then in a second child with that cache kept.

One command on a machine with a GPU (bench/GPU.md): ``python3 -m bench.bench_gpu --mitsuba PACK`` writes
``bench/results/gpu.json`` and the REPORT.md section. Where numba-cuda finds no GPU, or only its simulator, it says so
and exits 2 without writing a results file: no figure here is ever estimated. ``--smoke`` runs every section on tiny
sizes in numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``) and writes to a temporary path: it proves the code
paths, its figures mean nothing (tests/bench/test_bench_gpu.py runs it).
"""

from __future__ import annotations

import argparse
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
if str(ROOT) not in sys.path:   # `python3 bench/bench_gpu.py` on a machine where lumenlink is not installed
    sys.path.insert(0, str(ROOT))

MITSUBA_ENV = "LUMENLINK_MITSUBA"
MITSUBA_VARIANT = "cuda_ad_rgb"
SECTIONS = ("compile", "rays", "commit", "photons")
#: a time-to-target query longer than this is run once, not repeated
LONG_RUN_S = 5.0
#: what ``bench/bench_transport.py`` measured on 2 CPU cores for the time to 1 % at 100 floor points (backward)
TRANSPORT_CPU_2_CORES_S = 3.2
#: issue 27's targets (benchmark, not timed tests)
TARGETS = {"scene3_incoherent_mrays": 100.0, "scene3_camera_mrays": 300.0, "time_to_1pct_s": 0.2,
           "compile_s": 10.0, "commit_s": 1e-3}


class NoGPU(SystemExit):
    """No GPU to measure on: the message says why; nothing is written."""

    def __init__(self, why: str):
        super().__init__(f"bench_gpu: {why}. Nothing was measured and no results file was written "
                         "(this benchmark never writes estimated figures); run it on a machine with a CUDA GPU "
                         "(bench/GPU.md).")
        self.code = 2


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


_CACHE: tempfile.TemporaryDirectory | None = None


def share_cache_with_children() -> str | None:
    """Point this process's numba cache at a new, empty temporary directory before numba is imported (where it is
    not yet), so that the compile section's first child finds it empty and this process then loads what the
    children compiled instead of compiling it again (minutes of a 10-minute device call). The directory, or None."""
    global _CACHE
    if "numba" in sys.modules:
        return None
    chosen = os.environ.get("NUMBA_CACHE_DIR")
    if chosen and (not Path(chosen).exists() or not any(Path(chosen).iterdir())):
        return chosen   # a caller's own empty cache (bench/gpu_card.py shares one across its steps): keep it
    if _CACHE is None:
        _CACHE = tempfile.TemporaryDirectory(prefix="lumenlink-numba-")
        os.environ["NUMBA_CACHE_DIR"] = _CACHE.name
    return _CACHE.name


def log(msg: str) -> None:
    print(f"bench_gpu [{time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def median(xs) -> float:
    return float(statistics.median(xs))


# ---------------------------------------------------------------- the device
def find_gpu(smoke: bool) -> str:
    """The device's name ("cuda:0 NVIDIA H100 80GB HBM3"); :class:`NoGPU` where there is none to measure on. In
    ``smoke`` the simulator is required instead."""
    from tracer.gpu.device import find_cuda

    name, why = find_cuda()
    if smoke:
        if name != "cuda:0 simulator":
            raise SystemExit(f"bench_gpu --smoke: numba-cuda's simulator did not start ({name or why})")
        return name
    if name is None:
        raise NoGPU(f"no GPU found: {why}")
    if name.endswith("simulator"):
        raise NoGPU("numba-cuda runs only its simulator here (NUMBA_ENABLE_CUDASIM=1), which is no GPU")
    return name


def device_info(name: str) -> dict:
    import numba

    from tracer.gpu import cuda as _cuda

    cuda = _cuda()
    info = {"name": name, "numba": numba.__version__, "numpy": np.__version__}
    try:
        from importlib.metadata import version

        info["numba_cuda"] = version("numba-cuda")
    except Exception:   # noqa: BLE001 - a version we cannot read is only left out
        pass
    if not name.endswith("simulator"):
        try:   # descriptive only: a field numba-cuda cannot read is left out, the run goes on
            dev = cuda.get_current_device()
            info["compute_capability"] = ".".join(map(str, dev.compute_capability))
            info["multiprocessors"] = int(dev.MULTIPROCESSOR_COUNT)
            info["memory_gib"] = round(cuda.current_context().get_memory_info()[1] / 2**30, 1)
            info["driver"] = ".".join(map(str, cuda.cudadrv.driver.driver.get_version()))
        except Exception as exc:   # noqa: BLE001
            info["unread"] = f"{type(exc).__name__}: {exc}"
    return info


def cpu_threads() -> int:
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
            import bench.bench_gpu as b
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


# ---------------------------------------------------------------- run
def measure(sizes: Sizes, device: str, mitsuba: str | None, sections=SECTIONS, variant: str = MITSUBA_VARIANT,
            cache_dir: str | None = None) -> dict:
    """Every section asked for, on the device found; the result dict (with its ``markdown``)."""
    out: dict = {"device": device, "device_info": device_info(device), "cpu_threads": cpu_threads(),
                 "sections": list(sections), "sizes": sizes.__dict__, "targets": TARGETS}
    if "compile" in sections:   # first: a child compiling alone
        out["compile"] = compile_section(sizes, cache_dir)
    cases = None
    if "rays" in sections or "commit" in sections:
        log("building scene 3 and the bumpy sphere")
        cases = build_cases(sizes)
    if "rays" in sections:
        peer = Mitsuba(mitsuba, variant)
        out["rows"], out["builds"] = ray_rows(cases, sizes, peer)
        out["optix"] = {"variant": variant, "version": peer.version, "skipped": peer.skipped}
    if "commit" in sections:
        log("commit after a move")
        out["commit"] = commit_after_move(cases[0], sizes)
    if "photons" in sections:
        out["photons"] = photons_section(sizes)
    out["markdown"] = markdown(out)
    return out


def run(quick: bool = False) -> dict:
    """`bench.run`'s entry (``lumenlink bench --only gpu``): :class:`NoGPU` (exit 2, nothing written) without a GPU;
    the packed Mitsuba from ``LUMENLINK_MITSUBA``."""
    cache = share_cache_with_children()
    try:
        device = find_gpu(smoke=False)
    except NoGPU as exc:
        print(exc.args[0], file=sys.stderr)
        raise
    return measure(QUICK if quick else FULL, device, os.environ.get(MITSUBA_ENV), cache_dir=cache)


# ---------------------------------------------------------------- report
def _f(x, nd: int = 1) -> str:
    if x is None:
        return "—"
    return f"{x:,.{nd}f}"


def markdown(r: dict) -> str:
    md = [f"Device: **{r['device']}**; CPU columns on all {r['cpu_threads']} threads of its host. Issue 27's targets: "
          "scene 3 incoherent ≥ 100 Mrays/s, camera ≥ 300 (parity with OptiX the goal); time to 1 % at 100 floor "
          "points ≤ 0.2 s warm; first-use compile ≤ 10 s; commit after a move ≤ 1 ms with the upload.", ""]
    if "rows" in r:
        o = r["optix"]
        md += [f"### Closest hit (Mrays/s, median of {r['sizes']['repeats']} rounds, warm)", "",
               "Each round times ours on the GPU, the two Mitsuba calls and ours on the CPU one after the other on the "
               "same rays; a ratio (as speeds) is the median of the rounds' ratios.", "",
               "*GPU*: our closest-hit kernel (`tracer.gpu.traverse`, the CPU's own walk compiled by numba-cuda) over "
               "rays already on the card, launch to device sync; *end to end*: `DeviceScene.intersect` with host "
               f"arrays in and out. *OptiX*: Mitsuba 3 `{o['variant']}` ({o['version'] or 'not loaded'}) on the same "
               "card and rays, `ray_intersect` (t, primitive, uv, normal evaluated) on the flattened scene; "
               "*prelim.*: `ray_intersect_preliminary`. *CPU*: `Scene.intersect` on all threads. *Same hit*: the "
               "fraction of rays whose instance and primitive the GPU and the CPU agree on.", "",
               "| scene | rays | GPU | end to end | OptiX | prelim. | GPU / OptiX | CPU | threads | GPU / CPU | "
               "hit fraction | same hit |",
               "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
        for w in r["rows"]:
            md.append(f"| {w['scene']} | {w['rays']} ({w['n_rays']:,}) | {_f(w['gpu_mrays'])} | "
                      f"{_f(w['gpu_end_to_end_mrays'])} | {_f(w['optix_mrays'])} | "
                      f"{_f(w['optix_preliminary_mrays'])} | {_f(w['gpu_over_optix'], 2)} | "
                      f"{_f(w['cpu_mrays'], 2)} | {w['cpu_threads']} | {_f(w['gpu_over_cpu'], 1)} | "
                      f"{w['hit_fraction']:.4f} | {w['gpu_cpu_same_hit']:.6f} |")
        agree = [w["optix_cpu_hit_agreement"] for w in r["rows"] if "optix_cpu_hit_agreement" in w]
        if agree:
            md += ["", f"Mitsuba and ours hit or miss alike for at least {min(agree):.6f} of the rays in every row; "
                       f"GPU and CPU hit the same primitive for at least "
                       f"{min(w['gpu_cpu_same_hit'] for w in r['rows']):.6f}."]
        if o["skipped"]:
            md += ["", f"OptiX columns not measured: {o['skipped']}."]
    if "commit" in r:
        c = r["commit"]
        md += ["", f"### Commit after moving one object of {c['objects']:,} (median of {c['moves']})", "",
               f"Commit {c['commit_s'] * 1e3:.3f} ms + upload of the new revision {c['upload_s'] * 1e3:.3f} ms = "
               f"**{c['commit_and_upload_s'] * 1e3:.3f} ms** (worst {c['max_commit_and_upload_s'] * 1e3:.3f} ms); "
               f"uploaded {c['uploaded_bytes']:,} bytes in {len(c['uploaded_fields'])} fields "
               f"({', '.join(c['uploaded_fields'])}); bottom levels rebuilt: {c['blas_built']}."]
    if "photons" in r:
        p = r["photons"]
        md += ["", "### Photons in the diffuse room (bench/bench_transport.py)", "",
               f"| where | ran on (the answer's backend) | forward photons/s | time to {r['sizes']['target']:.0%} at "
               f"{r['sizes']['room_points'] ** 2} floor points, backward | forward |",
               "| --- | --- | ---: | ---: | ---: |"]
        for key, label in (("gpu", f"GPU ({r['device']})"), ("cpu", f"CPU, {p['cpu_threads']} threads")):
            if key not in p:
                md.append(f"| {label} | — | — | — | — |")
                continue
            b = p[key]["rate"].get("backend") or {}
            ran = b.get("device") or f"{b.get('name', '?')}, {b.get('threads', '?')} threads"
            if b.get("fallback"):   # CudaBackend handed the query to the CPU (a scene that does not fit)
                ran += f" ({b['fallback']})"
            tt = p[key]["to_target"]

            def cell(e, tt=tt):
                x = tt.get(e, {})
                if "seconds" not in x:
                    return "—"
                return (f"{x['seconds']:.3f} s ({x['stop_reason']}, worst {x['worst_relative_error']:.4f}, "
                        f"{x['runs']} run{'s' if x['runs'] > 1 else ''})")

            md.append(f"| {label} | {ran} | {p[key]['rate']['photons_per_second']:,.0f} | {cell('backward')} | "
                      f"{cell('forward')} |")
        md.append("")
        md.append(f"On 2 CPU cores bench_transport measured {TRANSPORT_CPU_2_CORES_S} s to 1 % (backward).")
        if p.get("gpu_skipped"):
            md.append(f"GPU rows not measured: {p['gpu_skipped']}.")
        if "gpu" in p:
            zs = {e: x["max_abs_z_vs_cpu"] for e, x in p["gpu"]["to_target"].items() if "max_abs_z_vs_cpu" in x}
            if zs:
                md.append("GPU against CPU answers, largest |ΔE| / σ combined over the points: " + ", ".join(
                    f"{e} {z:.2f}" for e, z in zs.items()) + " (agreement: ≤ 4).")
    if "card" in r:
        md += ["", f"### The card run's steps (bench/gpu_card.py, one call of {r['card']['budget_s']:.0f} s)", "",
               "| step | exit | seconds | checks (the simulator tests' checks, a card's tolerances) |",
               "| --- | --- | ---: | --- |"]
        for name, st in r["card"]["steps"].items():
            checks = st.get("checks") or {}
            shown = ", ".join(f"{k} {v:.2f}" if isinstance(v, float) else f"{k} {'yes' if v else 'NO'}"
                              for k, v in checks.items()) or st.get("why", "—")
            md.append(f"| {name} | {st['rc']} | {st.get('seconds', '—')} | {shown} |")
    if "compile" in r:
        c = r["compile"]
        md += ["", "### First use of the GPU kernels (child processes)", ""]
        for label, what in (("first", "empty numba cache" if c["cold_cache"] else "default numba cache"),
                            ("second", "the cache the first left")):
            x = c.get(label, {})
            if "error" in x:
                md.append(f"- {label} process ({what}): failed: `{x['error'][-300:]}`")
                continue
            photons = (f", forward photon kernel {x['forward_photons_first_use_s']:.2f} s"
                       if "forward_photons_first_use_s" in x else f"; photons: {x.get('photons_skipped', '—')}")
            md.append(f"- {label} process ({what}): closest-hit kernel {x['closest_kernel_s']:.2f} s, any-hit "
                      f"{x['any_kernel_s']:.2f} s{photons} (CPU kernels before them {x['cpu_first_use_s']:.2f} s, "
                      f"import {x['import_s']:.2f} s)")
    return "\n".join(md)


# ---------------------------------------------------------------- command line
def write_results(res: dict, path: Path | None) -> Path:
    """``res`` to ``path`` (default bench/results/gpu.json, then REPORT.md rebuilt), stamped as `bench.run` does."""
    from bench import run as bench_run

    res.update(date=res.get("date") or time.strftime("%Y-%m-%d %H:%M:%S"),
               machine=res.get("machine") or bench_run.machine())
    target = path or bench_run.RESULTS / "gpu.json"
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(json.dumps(res, indent=2, default=float))
    if path is None:
        log(f"report {bench_run.write_report()}")
    return target


def merge(files: list[str]) -> dict:
    """Results of split runs (``--sections``) on one device joined, later files over earlier ones."""
    parts = [json.loads(Path(f).read_text()) for f in files]
    cards = [p for p in parts if "steps" in p]   # bench/gpu_card.py's card.json: its checks, beside the figures
    parts = [p for p in parts if "steps" not in p]
    devices = {p.get("device") for p in parts}
    if len(devices) != 1 or any(p.get("smoke") for p in parts):
        raise SystemExit(f"bench_gpu --merge: the files come from different devices or smoke runs: {sorted(devices)}")
    res: dict = {}
    for p in parts:
        res.update({k: v for k, v in p.items() if k != "sections"})
    res["sections"] = [s for s in SECTIONS if any(s in p.get("sections", []) for p in parts)]
    for card in cards:
        res["card"] = {"nvidia_smi": card.get("nvidia_smi"), "budget_s": card.get("budget_s"),
                       "steps": {n: {k: v for k, v in st.items() if k in ("rc", "seconds", "checks", "why")}
                                 for n, st in card["steps"].items()}}
        res["machine"] = f"device host of {card.get('nvidia_smi')} ({res.get('cpu_threads')} CPU threads)"
    res["markdown"] = markdown(res)
    return res


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python3 -m bench.bench_gpu", description=__doc__.split("\n\n")[0])
    ap.add_argument("--mitsuba", default=os.environ.get(MITSUBA_ENV),
                    help=f"packed Mitsuba 3 (the .tar.xz of shared/tools/pack-mitsuba-cuda, or the directory it was "
                         f"unpacked into); default ${MITSUBA_ENV}; without it the OptiX column is skipped")
    ap.add_argument("--mitsuba-variant", default=MITSUBA_VARIANT, help=argparse.SUPPRESS)   # llvm_ad_rgb: a CPU check
    ap.add_argument("--quick", action="store_true", help="1M rays only, fewer moves, shorter budgets")
    ap.add_argument("--sections", default=",".join(SECTIONS),
                    help=f"comma-separated subset of {','.join(SECTIONS)} (to split a run across device calls; "
                         "join the parts with --merge)")
    ap.add_argument("--out", help="write the JSON here instead of bench/results/gpu.json (--smoke: a temporary file "
                                  "by default)")
    ap.add_argument("--merge", nargs="+", metavar="JSON",
                    help="join the JSON files of split runs into bench/results/gpu.json and REPORT.md (no GPU needed)")
    ap.add_argument("--smoke", action="store_true",
                    help="tiny sizes in numba-cuda's simulator, written to --out or a temporary file: proves the code "
                         "paths; its figures mean nothing")
    args = ap.parse_args(argv)
    if args.merge:
        path = write_results(merge(args.merge), Path(args.out) if args.out else None)
        log(f"merged into {path}")
        return 0
    sections = tuple(s for s in args.sections.split(",") if s)
    bad = set(sections) - set(SECTIONS)
    if bad:
        ap.error(f"unknown sections {sorted(bad)}; known: {', '.join(SECTIONS)}")
    if args.smoke:
        os.environ["NUMBA_ENABLE_CUDASIM"] = "1"   # before numba is imported: nothing above imports it
        device = find_gpu(smoke=True)
        res = measure(SMOKE, device, args.mitsuba, sections, args.mitsuba_variant)
        res.update(smoke=True)
        out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="lumenlink-bench-gpu-")) / "gpu.json"
        write_results(res, out)
        print(res["markdown"])
        log(f"smoke run (simulator, figures meaningless) written to {out}")
        return 0
    cache = share_cache_with_children()
    try:
        device = find_gpu(smoke=False)
    except NoGPU as exc:
        print(exc.args[0], file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    res = measure(QUICK if args.quick else FULL, device, args.mitsuba, sections, args.mitsuba_variant, cache)
    res.update(quick=args.quick, wall_seconds=time.perf_counter() - t0)
    path = write_results(res, Path(args.out) if args.out else None)
    print(res["markdown"])
    log(f"written {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
