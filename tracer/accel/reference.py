"""A slow, obviously correct tracer for tests: every ray against every triangle, in world space.

Each instance's triangles are mapped to world space with its 4x4 matrix and tested with the
Möller–Trumbore formula in float64 numpy (no acceleration structure, no object-space trick, no
shared code with the fast path), so agreement between the two is evidence, not tautology.
Sensors are ignored, as by the fast closest-hit query.
"""

from __future__ import annotations

import numpy as np

from tracer.scene import Hits, Scene


def _world_triangles(scene: Scene) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """World-space triangles (T, 3, 3), their instance ids, primitive ids and unit world normals."""
    tris, insts, prims, normals = [], [], [], []
    for i in scene.instances():
        if scene.is_sensor(i):
            continue
        v, f, _ = scene.geometry_arrays(scene.instance_geometry(i))
        if len(f) == 0:
            continue
        m = scene.instance_transform(i)
        obj = v.astype(np.float64)[f.astype(np.int64)]  # (m, 3, 3)
        world = obj @ m[:3, :3].T + m[:3, 3]
        n_obj = np.cross(obj[:, 1] - obj[:, 0], obj[:, 2] - obj[:, 0])
        n_w = n_obj @ np.linalg.inv(m[:3, :3])  # rows: inv(L)^T n
        ln = np.linalg.norm(n_w, axis=1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            n_w = np.where(ln > 0, n_w / ln, 0.0)
        tris.append(world)
        insts.append(np.full(len(f), i))
        prims.append(np.arange(len(f)))
        normals.append(n_w)
    if not tris:
        return np.empty((0, 3, 3)), np.empty(0, np.int64), np.empty(0, np.int64), np.empty((0, 3))
    return np.concatenate(tris), np.concatenate(insts), np.concatenate(prims), np.concatenate(normals)


def ray_triangle_t(o: np.ndarray, d: np.ndarray, tri: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Möller–Trumbore of one ray against all triangles: ``(t, u, v)``, ``t = inf`` where missed."""
    e1 = tri[:, 1] - tri[:, 0]
    e2 = tri[:, 2] - tri[:, 0]
    p = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, p)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        s = o - tri[:, 0]
        u = np.einsum("ij,ij->i", s, p) * inv
        q = np.cross(s, e1)
        v = (q @ d) * inv
        t = np.einsum("ij,ij->i", e2, q) * inv
        ok = (det != 0) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0) & np.isfinite(t)
    return np.where(ok, t, np.inf), u, v


def intersect(scene: Scene, origins: np.ndarray, directions: np.ndarray, t_max: float = np.inf) -> Hits:
    """Closest hits by brute force; same fields and conventions as :meth:`tracer.Scene.intersect`."""
    tri, insts, prims, normals = _world_triangles(scene)
    k = len(origins)
    out = Hits(np.full(k, np.inf), np.full(k, -1), np.full(k, -1), np.zeros(k), np.zeros(k), np.zeros((k, 3)))
    for r in range(k):
        if len(tri) == 0:
            continue
        t, u, v = ray_triangle_t(np.asarray(origins[r], float), np.asarray(directions[r], float), tri)
        j = int(np.argmin(t))
        if t[j] < t_max:
            out.t[r] = t[j]
            out.instance[r] = insts[j]
            out.primitive[r] = prims[j]
            out.u[r] = u[j]
            out.v[r] = v[j]
            out.normal[r] = normals[j]
    return out


def all_hits(scene: Scene, origin: np.ndarray, direction: np.ndarray) -> list[tuple[float, int, int]]:
    """Every ``(t, instance, primitive)`` the ray hits, sorted by t (for tie analysis in tests)."""
    tri, insts, prims, _ = _world_triangles(scene)
    t, _, _ = ray_triangle_t(np.asarray(origin, float), np.asarray(direction, float), tri)
    hit = np.flatnonzero(np.isfinite(t))
    return sorted((float(t[j]), int(insts[j]), int(prims[j])) for j in hit)


# ---------------------------------------------------------------- scene generators (tests, bench)
def icosphere(subdivisions: int, radius: float = 1.0, center=(0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """A closed, outward-wound icosphere: vertices (n, 3) float64, triangles (m, 3) int64, m = 20 4^s."""
    p = (1.0 + 5.0**0.5) / 2.0
    v = [(-1, p, 0), (1, p, 0), (-1, -p, 0), (1, -p, 0), (0, -1, p), (0, 1, p), (0, -1, -p), (0, 1, -p),
         (p, 0, -1), (p, 0, 1), (-p, 0, -1), (-p, 0, 1)]
    verts = [np.array(x, float) / np.linalg.norm(x) for x in v]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
             (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11),
             (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    for _ in range(subdivisions):
        cache: dict[tuple[int, int], int] = {}

        def mid(a: int, b: int, cache: dict[tuple[int, int], int] = cache) -> int:
            key = (min(a, b), max(a, b))
            if key not in cache:
                m = verts[a] + verts[b]
                verts.append(m / np.linalg.norm(m))
                cache[key] = len(verts) - 1
            return cache[key]

        new = []
        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            new += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = new
    return np.array(verts) * radius + np.asarray(center, float), np.array(faces, np.int64)


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """A uniformly random 3x3 rotation (QR of a Gaussian matrix, sign-fixed)."""
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def random_affine(rng: np.random.Generator, scale: float = 1.0, spread: float = 3.0, mirror: bool | None = None,
                  anisotropy: float = 3.0) -> np.ndarray:
    """A random 4x4 affine map: rotation, non-uniform scale (ratio up to ``anisotropy``), optional
    mirroring (random when None), translation within ``spread``."""
    s = scale * np.exp(rng.uniform(-0.5, 0.5, 3) * np.log(anisotropy))
    if mirror is None:
        mirror = bool(rng.integers(2))
    if mirror:
        s[rng.integers(3)] *= -1.0
    m = np.eye(4)
    m[:3, :3] = random_rotation(rng) @ np.diag(s) @ random_rotation(rng)
    m[:3, 3] = rng.uniform(-spread, spread, 3)
    return m


def random_mesh(rng: np.random.Generator, n_triangles: int, size: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """A soup of ``n_triangles`` random triangles in a cube of side ``size`` (shared vertices sometimes)."""
    n_v = max(3, int(n_triangles * 1.5))
    v = rng.uniform(-size / 2, size / 2, (n_v, 3))
    f = np.stack([rng.choice(n_v, 3, replace=False) for _ in range(n_triangles)])
    return v, f
