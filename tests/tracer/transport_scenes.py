"""Meshes and closed-form references shared by the light-transport tests (test_transport_*, test_optics_*)."""

from __future__ import annotations

import math

import numpy as np

from tracer.accel import reference
from tracer.scene import Scene


def quad(p0, e1, e2):
    """Two triangles of the parallelogram p0 + s e1 + t e2; front side e1 × e2."""
    p0, e1, e2 = (np.asarray(x, float) for x in (p0, e1, e2))
    v = np.array([p0, p0 + e1, p0 + e1 + e2, p0 + e2])
    return v, np.array([[0, 1, 2], [0, 2, 3]])


def box(lo, hi):
    """Closed box with outward normals: (vertices (8, 3), triangles (12, 3))."""
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    v = np.array([[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0],
                  [x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]], float)
    t = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                  [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])
    return v, t


def icosphere(radius: float, subdivisions: int):
    """Closed triangulated sphere with outward normals, vertices on the sphere of `radius`."""
    return reference.icosphere(subdivisions, radius=radius)


def outward(v, t):
    """Triangles of a convex mesh reordered so that e1 × e2 points away from the centroid."""
    v, t = np.asarray(v, float), np.array(t)
    c = v.mean(axis=0)
    a, b, d = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    flip = np.einsum("ij,ij->i", np.cross(b - a, d - a), (a + b + d) / 3 - c) < 0
    t[flip] = t[flip][:, [0, 2, 1]]
    return v, t


def mesh_area(v, t) -> float:
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    return float(0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum())


def scene_of(*meshes, transform=None):
    """A committed scene with one instance per (vertices, triangles); returns (scene, [instance ids])."""
    s = Scene()
    ids = []
    for v, t in meshes:
        g = s.add_geometry(np.asarray(v, float), np.asarray(t))
        ids.append(s.add_instance(g, np.eye(4) if transform is None else transform))
    s.commit()
    return s, ids


def disk_average(fn, center, normal, radius, n_r=48, n_phi=96) -> float:
    """Average of fn(point (m, 3)) -> (m,) over a disk (Gauss–Legendre in r², uniform in φ)."""
    center, normal = np.asarray(center, float), np.asarray(normal, float)
    normal = normal / np.linalg.norm(normal)
    a = np.cross(normal, [1.0, 0, 0] if abs(normal[0]) < 0.9 else [0, 1.0, 0])
    a /= np.linalg.norm(a)
    b = np.cross(normal, a)
    x, w = np.polynomial.legendre.leggauss(n_r)
    s = 0.5 * (x + 1)          # s = (ρ/r)², uniform in area
    phi = (np.arange(n_phi) + 0.5) * 2 * math.pi / n_phi
    rho = radius * np.sqrt(s)
    pts = (center[None, None, :] + rho[:, None, None] * (np.cos(phi)[None, :, None] * a
                                                         + np.sin(phi)[None, :, None] * b))
    vals = fn(pts.reshape(-1, 3)).reshape(n_r, n_phi)
    return float((0.5 * w[:, None] * vals).sum() / n_phi)


def point_source_e(intensity, source, normal):
    """Illuminance function of an isotropic point source on receivers with `normal` (no occlusion)."""
    source, normal = np.asarray(source, float), np.asarray(normal, float) / np.linalg.norm(normal)

    def fn(p):
        d = source[None, :] - p
        r = np.linalg.norm(d, axis=1)
        c = np.maximum(d @ normal / r, 0.0)
        return intensity * c / r ** 2

    return fn


def polygon_form_factor(p, n, poly) -> float:
    """Form factor from a differential area at p (unit normal n) to a planar polygon wholly in front of it
    (Lambert's contour integral): F = 1/(2π) Σ β_i n · unit(R_i × R_i+1)."""
    r = np.asarray(poly, float) - np.asarray(p, float)[None, :]
    total = 0.0
    for i in range(len(r)):
        a, b = r[i], r[(i + 1) % len(r)]
        c = np.cross(a, b)
        beta = math.atan2(np.linalg.norm(c), float(a @ b))
        total += beta * float(np.asarray(n) @ c) / np.linalg.norm(c)
    return abs(total) / (2 * math.pi)


def z_of(est, ref):
    """How many standard errors the estimate lies from the reference."""
    return np.abs(np.asarray(est.lux) - ref) / np.maximum(np.asarray(est.stderr), 1e-300)
