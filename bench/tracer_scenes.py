"""The tracer benchmark's scenes and rays, shared by :mod:`bench.bench_tracer`, :mod:`bench.tracer_profile`,
:mod:`bench.bench_gpu` and the probes: the paper's dynamic scenes regenerated synthetically (ribbons of triangles
with the paper's object and triangle counts), a bumpy sphere, incoherent and camera rays, and the same triangles in
Embree (embreex) flat or instanced. Seeded, so every bench sees the same rays."""

from __future__ import annotations

import time

import numpy as np

import tracer
from tracer.accel import reference


# ---------------------------------------------------------------- synthetic scenes
def triangle_counts(rng: np.random.Generator, n_objects: int, n_triangles: int) -> np.ndarray:
    """Per-object triangle counts (>= 1, log-normally spread) summing exactly to ``n_triangles``."""
    w = rng.lognormal(0.0, 1.0, n_objects)
    extra = n_triangles - n_objects
    c = 1 + np.floor(w / w.sum() * extra).astype(np.int64)
    short = n_triangles - int(c.sum())
    c[np.argsort(-w)[:short]] += 1
    return c


def ribbons(rng: np.random.Generator, counts: np.ndarray, world_size: float) -> tuple[list, list, np.ndarray]:
    """One wavy triangle strip per object (``counts[i]`` triangles, ``counts[i] + 2`` vertices), in object
    space of size ~1 (scaled with the triangle count), and a random placement for each.

    Returns per-object vertex arrays, triangle arrays and (n, 4, 4) transforms.
    """
    n = len(counts)
    nv = counts + 2
    voff = np.concatenate([[0], np.cumsum(nv)])
    k = np.arange(voff[-1]) - np.repeat(voff[:-1], nv)  # vertex index within its strip
    length = np.repeat(np.sqrt(counts) * 0.1 + 0.2, nv)
    span = np.repeat(nv - 1, nv).astype(float)
    s = k / span
    phase = np.repeat(rng.uniform(0, 2 * np.pi, n), nv)
    verts = np.stack([s * length, (k % 2) * 0.05 + 0.1 * np.sin(6 * s + phase), 0.1 * np.cos(4 * s + phase)], 1)
    toff = np.concatenate([[0], np.cumsum(counts)])
    j = np.arange(toff[-1]) - np.repeat(toff[:-1], counts)
    tris = np.stack([j, j + 1, j + 2], 1)
    v_list = np.split(verts, voff[1:-1])
    f_list = np.split(tris, toff[1:-1])
    mats = np.repeat(np.eye(4)[None], n, axis=0)
    for i in range(n):
        mats[i, :3, :3] = reference.random_rotation(rng)
    mats[:, :3, 3] = rng.uniform(0, world_size, (n, 3))
    return v_list, f_list, mats


def synth_scene(seed: int, n_objects: int, n_triangles: int) -> tuple[list, list, np.ndarray, float]:
    """A synthetic scene with exactly these counts; also returns its world size (m)."""
    rng = np.random.default_rng(seed)
    counts = triangle_counts(rng, n_objects, n_triangles)
    world = max(3.0, n_objects ** (1 / 3) * 0.8)
    v, f, m = ribbons(rng, counts, world)
    return v, f, m, world


def load_scene(v_list: list, f_list: list, mats: np.ndarray) -> tuple[tracer.Scene, list[int], float]:
    """Fresh scene with every object added (not committed); returns the ingest seconds."""
    t0 = time.perf_counter()
    scene = tracer.Scene()
    ids = [scene.add_instance(scene.add_geometry(v, f), m) for v, f, m in zip(v_list, f_list, mats, strict=True)]
    return scene, ids, time.perf_counter() - t0


# ---------------------------------------------------------------- rays
def bumpy_sphere(nu: int, nv: int) -> tuple[np.ndarray, np.ndarray]:
    """A closed-ish bumpy sphere grid with ``2 nu nv`` triangles (poles are fans of slivers)."""
    th = np.linspace(0, np.pi, nv + 1)
    ph = np.linspace(0, 2 * np.pi, nu + 1)[:-1]
    t, p = np.meshgrid(th, ph, indexing="ij")
    r = 1 + 0.05 * np.sin(9 * t) * np.sin(7 * p)
    v = np.stack([r * np.sin(t) * np.cos(p), r * np.sin(t) * np.sin(p), r * np.cos(t)], -1).reshape(-1, 3)
    idx = np.arange((nv + 1) * nu).reshape(nv + 1, nu)
    a, b = idx[:-1], np.roll(idx[:-1], -1, 1)
    c, d = idx[1:], np.roll(idx[1:], -1, 1)
    f = np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3), np.stack([b, c, d], -1).reshape(-1, 3)])
    return v, f


def incoherent_rays(rng, k: int, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    o = rng.uniform(lo, hi, (k, 3))
    d = rng.normal(size=(k, 3))
    return o, d / np.linalg.norm(d, axis=1, keepdims=True)


def shadow_t_max(rng, k: int, length: float) -> np.ndarray:
    """Shadow segments' lengths for any-hit rows: uniform in ``(0, length)``, float32 values (so Embree's float32
    ``tfar`` is the same segment)."""
    return rng.uniform(0.0, length, k).astype(np.float32).astype(np.float64)


def camera_rays(k: int, eye: np.ndarray, target: np.ndarray, fov_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Pinhole camera rays, row by row (coherent)."""
    n = int(round(np.sqrt(k)))
    w = target - eye
    w /= np.linalg.norm(w)
    u = np.cross(w, [0.0, 0.0, 1.0])
    u /= np.linalg.norm(u)
    v = np.cross(u, w)
    s = np.tan(np.radians(fov_deg) / 2)
    x, y = np.meshgrid(np.linspace(-s, s, n), np.linspace(-s, s, n))
    d = w + x.reshape(-1, 1) * u + y.reshape(-1, 1) * v
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return np.broadcast_to(eye, d.shape).copy(), d


def embree_scene(triangles_world: np.ndarray):
    """An embreex scene over world-space triangles (m, 3, 3), or None when embreex is missing."""
    try:
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh
    except ImportError:
        return None
    es = rtcore_scene.EmbreeScene()
    TriangleMesh(es, np.ascontiguousarray(triangles_world, np.float32))
    return es


def world_triangles(scene: tracer.Scene) -> np.ndarray:
    out = []
    for i in scene.instances():
        v, f, _ = scene.geometry_arrays(scene.instance_geometry(i))
        m = scene.instance_transform(i)
        out.append(v.astype(np.float64)[f.astype(np.int64)] @ m[:3, :3].T + m[:3, 3])
    return np.concatenate(out)


def embree_instanced(scene: tracer.Scene):
    """Embree over the same instances (one Embree scene per geometry, a top scene over them):
    ``(scene, our instance id of each Embree instance, build s)``, or None without embreex."""
    from bench import embree_instances

    if not embree_instances.available():
        return None
    ids = list(scene.instances())
    geoms = sorted({scene.instance_geometry(i) for i in ids})
    slot = {g: k for k, g in enumerate(geoms)}
    t0 = time.perf_counter()
    es = embree_instances.InstancedScene([scene.geometry_arrays(g)[:2] for g in geoms],
                                         [(slot[scene.instance_geometry(i)], scene.instance_transform(i)) for i in ids])
    return es, np.array(ids + [-1]), time.perf_counter() - t0
