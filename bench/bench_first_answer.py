"""Time to the first answer of a fresh install: `lumenlink serve` started with an empty numba cache, then, as a
new user's script would, a room with a Lambertian wall, a mirror and a glass block is pushed over REST, one
point light added, and a 100k-photon illuminance query asked. Measured from the moment the server process
starts to the moment the lux arrive (issue 18's target: ≤ 30 s).

The cold start with the warm-up runs `COLD_RUNS` times, each on an empty cache, and its median is the row. Side by
side in one run: the same with background compilation at start turned off (`--no-warm`: the first
query compiles for itself, as before), and with the numba cache warm (what every later start costs). Ratios
against the warm start say what compiling costs. The service runs as a real uvicorn process.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
import uuid as uuidlib
from pathlib import Path
from typing import Any

import numpy as np

from tracer.warmup import box

ROOT = Path(__file__).resolve().parents[1]
IDENT = [1.0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]


def _glb(v: np.ndarray, t: np.ndarray) -> tuple[str, bytes]:
    import trimesh

    from tracer.geometry_id import geometry_id

    return geometry_id(v, t), trimesh.Trimesh(v, t, process=False).export(file_type="glb")


PARTS = {"room": (box((0, 0, 0), (4, 4, 3)), {"type": "lambertian", "reflectance": 0.5}),
         "mirror": (box((3.9, 1, 0.5), (3.95, 3, 2.5)), {"type": "mirror", "reflectance": 0.9}),
         "glass": (box((1, 1, 0.5), (2, 2, 1)), {"type": "dielectric", "ior": 1.5})}


def _user(base: str, t_start: float) -> dict[str, Any]:
    """A new user's first session; seconds since the server process started at each step."""
    import httpx

    marks: dict[str, float] = {}
    with httpx.Client(base_url=base, timeout=600) as c:
        marks["health"] = time.perf_counter() - t_start
        sid = c.post("/scenes", json={"name": "first"}).json()["id"]
        root = str(uuidlib.uuid4())
        nodes = [{"uuid": root, "parent": None, "name": "room", "transform": IDENT, "geometry": None}]
        ids = {}
        for name, ((v, t), _) in PARTS.items():
            gid, data = _glb(v, t)
            c.put(f"/geometries/{gid}", content=data, headers={"content-type": "model/gltf-binary"}).raise_for_status()
            ids[name] = str(uuidlib.uuid4())
            nodes.append({"uuid": ids[name], "parent": root, "name": name, "transform": IDENT, "geometry": gid})
        c.put(f"/scenes/{sid}/document", json={"base_revision": 0, "length_unit": "m", "nodes": nodes}
              ).raise_for_status()
        marks["pushed"] = time.perf_counter() - t_start
        for name, (_, material) in PARTS.items():
            c.put(f"/scenes/{sid}/materials/{ids[name]}", json=material).raise_for_status()
        c.post(f"/scenes/{sid}/lights", json={"type": "point", "position": [2, 2, 2.5], "intensity_cd": 1000}
               ).raise_for_status()
        r = c.post(f"/scenes/{sid}/illuminance", json={"points": [[2.5, 2.5, 0.0], [3.0, 1.5, 0.0]],
                                                        "normals": [[0, 0, 1], [0, 0, 1]], "max_photons": 100_000})
        r.raise_for_status()
        marks["answered"] = time.perf_counter() - t_start
        answer = r.json()
    return {"seconds": marks, "compile_seconds": answer.get("compile_seconds"), "lux": answer["lux"],
            "effects": answer["effects"], "estimator": answer["estimator"]}


def _session(cache: Path, warm: bool) -> dict[str, Any]:
    """Start a server on a fresh data dir with numba cache `cache`, run the user's session, stop the server."""
    import socket

    import httpx

    with tempfile.TemporaryDirectory() as data:
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), PYTHONPATH=str(ROOT))
        args = [sys.executable, "-m", "lumenlink.cli", "serve", "--port", str(port), "--data-dir", data]
        if not warm:
            args.append("--no-warm")
        t_start = time.perf_counter()
        proc = subprocess.Popen(args, cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            base = f"http://127.0.0.1:{port}"
            while True:
                try:
                    if httpx.get(f"{base}/health", timeout=1).status_code == 200:
                        break
                except httpx.HTTPError:
                    time.sleep(0.05)
            out = _user(base, t_start)
            out["kernels"] = httpx.get(f"{base}/health").json()["kernels"]
        finally:
            proc.terminate()
            proc.wait(timeout=30)
    return out


#: cold starts with the warm-up, each on its own empty cache: their median is the row (one run varies by ±2 s)
COLD_RUNS = 3


def run(quick: bool = False) -> dict[str, Any]:
    sessions: dict[str, Any] = {}
    cold: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as cold_b:
        for k in range(1 if quick else COLD_RUNS):
            with tempfile.TemporaryDirectory() as cold_a:
                cold.append(_session(Path(cold_a), warm=True))
                if k == 0:
                    sessions["warm cache"] = _session(Path(cold_a), warm=True)
        if not quick:
            sessions["cold, no warm-up"] = _session(Path(cold_b), warm=False)
    order = sorted(range(len(cold)), key=lambda i: cold[i]["seconds"]["answered"])
    median = cold[order[len(cold) // 2]]
    sessions = {"cold, warm-up at start": {**median, "runs": [c["seconds"]["answered"] for c in cold]}, **sessions}
    warm = sessions["warm cache"]["seconds"]["answered"]
    rows = ["| start | health s | pushed s | first lux s | of which compiling s | vs warm cache |",
            "| --- | ---: | ---: | ---: | ---: | ---: |"]
    for name, s in sessions.items():
        m = s["seconds"]
        runs = f" (median of {', '.join(f'{x:.1f}' for x in s['runs'])})" if len(s.get("runs", ())) > 1 else ""
        rows.append(f"| {name} | {m['health']:.1f} | {m['pushed']:.1f} | **{m['answered']:.1f}**{runs} | "
                    f"{s['compile_seconds']:.1f} | ×{m['answered'] / warm:.1f} |")
    markdown = ("From `lumenlink serve` started (fresh data dir; numba cache empty for the cold rows) to the first "
                "lux of a room with a Lambertian wall, a mirror and a glass block, one point light, 100k photons, "
                f"through the real REST API; the cold start with the warm-up is the median of {len(cold)}, each on an "
                "empty cache. Target: first lux ≤ 30 s on a fresh install.\n\n" + "\n".join(rows))
    return {"sessions": sessions, "markdown": markdown}
