"""A feature given as a mesh: a closed convex triangle mesh (a lenslet, a measured dot profile) standing on its base.

The body: ``{"shape": "mesh", "vertices_mm": [[u, v, w], ...], "triangles": [[i, j, k], ...]}``, in mm, in the
feature's own frame: ``(u, v)`` from the feature's centre (the layout's site), ``w`` up from the support (for a pit,
into the part); the service reads a pushed geometry into it (``{"geometry": "<gid>"}``, `service.elements`). Vertices
at one position are one corner (a CAD mesh repeats them per face). The solid must be closed (each edge shared by two
triangles, oriented alike: outward or all inward), convex, and a height field over its base: the base faces lie at
``w = 0`` (its lowest vertices) and every other face looks up, at most `STEEPEST_DEG` from the support's normal (a
hit is kept as its plane point and the height above it: a steeper face would lose its height). A convex solid is the
intersection of its faces' half-spaces, so the inner tracer walks the distinct face planes (``P``, at most
`MAX_FACES`) as it walks a pyramid's four: one table for every copy of the feature, whatever their number
(`tracer.elements.table` packs it once per element).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from tracer.elements.checks import ElementError
from tracer.elements.shapes.base import half_space
from tracer.jit import njit

NAME = "mesh"
FIELDS = {"vertices_mm", "triangles"}
LAYOUTS = ("grid", "hex", "density", "points")
ROUND = True
RIDGE = False
#: a square pyramid 0.2 mm across and 0.08 mm high, as five vertices and six triangles (two of them its base)
EXAMPLE = {"shape": NAME,
           "vertices_mm": [[-0.1, -0.1, 0.0], [0.1, -0.1, 0.0], [0.1, 0.1, 0.0], [-0.1, 0.1, 0.0], [0.0, 0.0, 0.08]],
           "triangles": [[0, 2, 1], [0, 3, 2], [0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]]}
MAX_VERTICES = 20_000
MAX_TRIANGLES = 40_000
MAX_FACES = 4096          # distinct face planes: each ray that reaches a feature's box tests each
STEEPEST_DEG = 89.0       # how far from the support's normal a face other than the base may look
TOLERANCE = 1e-6          # of the mesh's size: how far a vertex may sit off the base plane or outside a face


def parse(f: dict) -> tuple[dict, float, float, float, np.ndarray]:
    vertices = _table(f["vertices_mm"], "feature.vertices_mm", "[u, v, w] in mm", np.float64)
    triangles = _table(f["triangles"], "feature.triangles", "[i, j, k] vertex indices", np.int64)
    if len(vertices) < 4 or len(vertices) > MAX_VERTICES:
        raise ElementError(f"feature.vertices_mm has {len(vertices)} vertices; a solid has at least 4, and a feature "
                           f"at most {MAX_VERTICES}")
    if len(triangles) > MAX_TRIANGLES:
        raise ElementError(f"feature.triangles has {len(triangles)} triangles, more than {MAX_TRIANGLES}: simplify "
                           f"the mesh")
    if not np.isfinite(vertices).all():
        raise ElementError(f"feature.vertices_mm[{int(np.argwhere(~np.isfinite(vertices))[0][0])}] is not finite")
    bad = np.argwhere((triangles < 0) | (triangles >= len(vertices)))
    if len(bad):
        t, c = (int(x) for x in bad[0])
        raise ElementError(f"feature.triangles[{t}][{c}] = {int(triangles[t, c])} is no vertex index (0 to "
                           f"{len(vertices) - 1})")
    size = float(np.ptp(vertices, axis=0).max())
    tol = TOLERANCE * size
    low = float(vertices[:, 2].min())
    h = float(vertices[:, 2].max())
    if abs(low) > tol:
        raise ElementError(f"feature.vertices_mm: the lowest vertex is at w = {low:g} mm; a feature stands on the "
                           f"support, so its base lies at w = 0 (w along the support's normal): move the mesh")
    if h <= tol:
        raise ElementError("feature.vertices_mm: the mesh is flat (no vertex above w = 0): a feature has a height")
    # a mesh as CAD writes it repeats a vertex for each face it bounds: vertices at one position are one corner
    _, first, inverse = np.unique(vertices, axis=0, return_index=True, return_inverse=True)
    corners = first[inverse.ravel()][triangles]
    _check_closed(corners)
    planes = _planes(vertices, corners, tol)
    _convex(vertices, planes, tol)
    a = float(np.hypot(vertices[:, 0], vertices[:, 1]).max())
    canon = {"shape": NAME, "vertices_mm": vertices.tolist(), "triangles": triangles.tolist()}
    return canon, a, h, 0.0, planes


def _table(x: Any, where: str, row: str, dtype: type) -> np.ndarray:
    """Rows of three numbers (integers for indices) as an (N, 3) array; `ElementError` naming `where` otherwise."""
    try:
        arr = np.asarray(x)
    except (TypeError, ValueError):
        arr = np.zeros(0)
    if arr.ndim != 2 or arr.shape[1] != 3 or len(arr) == 0 or arr.dtype.kind not in ("iu" if dtype is np.int64
                                                                                       else "iuf"):
        raise ElementError(f"{where} must be a non-empty list of {row}")
    return arr.astype(dtype)


def _check_closed(triangles: np.ndarray) -> None:
    """`ElementError` where an edge has no triangle across it, or two triangles run it the same way (a closed surface
    oriented alike; whether outward or inward, `_planes` tells by the sign of the volume)."""
    n = int(triangles.max()) + 1
    heads = triangles.ravel()
    tails = np.roll(triangles, -1, axis=1).ravel()
    directed = heads * n + tails
    keys, first, counts = np.unique(directed, return_index=True, return_counts=True)
    if (heads == tails).any():
        t = int(np.argmax(heads == tails)) // 3
        raise ElementError(f"feature.triangles[{t}] repeats a vertex: a triangle has three corners")
    if (counts > 1).any():
        e = int(first[np.argmax(counts > 1)])
        raise ElementError(f"feature.triangles: edge ({int(heads[e])}, {int(tails[e])}) is run the same way by two "
                           f"triangles: orient every triangle alike (all outward or all inward) on a closed surface")
    lonely = ~np.isin(tails * n + heads, keys)
    if lonely.any():
        e = int(np.argmax(lonely))
        raise ElementError(f"feature.triangles: the mesh is not closed: edge ({int(heads[e])}, {int(tails[e])}) of "
                           f"triangle {e // 3} has no triangle across it; a feature is a closed solid")


def _planes(vertices: np.ndarray, triangles: np.ndarray, tol: float) -> np.ndarray:
    """The distinct planes ``(nu, nv, nw, c)`` of the faces above the base (unit outward normals), checked."""
    p0, p1, p2 = (vertices[triangles[:, k]] for k in range(3))
    normal = np.cross(p1 - p0, p2 - p0)
    area2 = np.linalg.norm(normal, axis=1)
    if (area2 <= tol * tol).any():
        t = int(np.argmax(area2 <= tol * tol))
        raise ElementError(f"feature.triangles[{t}] has no area (its corners are on one line)")
    volume = float(np.einsum("ij,ij->i", p0, np.cross(p1, p2)).sum()) / 6.0
    normal = normal / area2[:, None] * (1.0 if volume > 0.0 else -1.0)   # outward
    base = (np.abs(vertices[triangles, 2]) <= tol).all(axis=1)
    steep = ~base & (normal[:, 2] < math.cos(math.radians(STEEPEST_DEG)))
    if steep.any():
        t = int(np.argmax(steep))
        tilt = math.degrees(math.acos(max(-1.0, min(1.0, float(normal[t, 2])))))
        raise ElementError(f"feature.triangles[{t}] looks {tilt:.3g} deg away from the support's normal: a feature is "
                           f"a height field over its base, so every face but the base (at w = 0) must look up, at "
                           f"most {STEEPEST_DEG:g} deg from the normal")
    up = normal[~base]
    plane = np.column_stack([up, np.einsum("ij,ij->i", up, p0[~base])]) + 0.0   # no -0.0 in the table
    # one plane per flat face (a quad is two triangles): normals equal to 1e-9, offsets to 1e-9 of the mesh's size
    _, keep = np.unique(np.round(plane / np.array([1e-9, 1e-9, 1e-9, 1e-3 * tol])), axis=0, return_index=True)
    plane = plane[np.sort(keep)]
    if len(plane) > MAX_FACES:
        raise ElementError(f"feature.triangles: the mesh has {len(plane)} distinct face planes, more than "
                           f"{MAX_FACES} (each ray that reaches a feature tests each): simplify the mesh")
    return np.ascontiguousarray(plane)


def _convex(vertices: np.ndarray, planes: np.ndarray, tol: float) -> None:
    """`ElementError` where a vertex lies outside a face's plane: the solid is not convex."""
    for k0 in range(0, len(planes), 256):
        block = planes[k0:k0 + 256]
        out = vertices @ block[:, :3].T - block[:, 3]
        if (out > tol).any():
            i, k = np.unravel_index(int(np.argmax(out)), out.shape)
            raise ElementError(f"feature: the mesh is not convex (vertex {int(i)} lies {float(out[i, k]):.3g} mm "
                               f"outside a face's plane): a feature is found as the intersection of its faces' "
                               f"half-spaces; give its convex hull, or split it into convex features")


@njit(cache=True, error_model="numpy", _nrt=False)
def interval(a, h, rs, slope, P, cu, cv, ou, ov, ow, du, dv, dw):
    # the feature's box first: most rays that reach a feature's cell pass beside it
    lo, hi, _, _ = half_space(1.0, 0.0, 0.0, cu + a, ou, ov, ow, du, dv, dw, -math.inf, math.inf)
    lo, hi, _, _ = half_space(-1.0, 0.0, 0.0, a - cu, ou, ov, ow, du, dv, dw, lo, hi)
    lo, hi, _, _ = half_space(0.0, 1.0, 0.0, cv + a, ou, ov, ow, du, dv, dw, lo, hi)
    lo, hi, _, _ = half_space(0.0, -1.0, 0.0, a - cv, ou, ov, ow, du, dv, dw, lo, hi)
    lo, hi, _, _ = half_space(0.0, 0.0, 1.0, h, ou, ov, ow, du, dv, dw, lo, hi)
    if not lo < hi:
        return math.inf, -math.inf
    lo = -math.inf
    hi = math.inf
    for k in range(P.shape[0]):
        nu = P[k, 0]
        nv = P[k, 1]
        lo, hi, _, _ = half_space(nu, nv, P[k, 2], P[k, 3] + nu * cu + nv * cv, ou, ov, ow, du, dv, dw, lo, hi)
        if not lo < hi:
            return math.inf, -math.inf
    return lo, hi


@njit(cache=True, error_model="numpy", _nrt=False)
def covers(a, P, du, dv):
    for k in range(P.shape[0]):
        if P[k, 0] * du + P[k, 1] * dv > P[k, 3]:
            return False
    return True


@njit(cache=True, error_model="numpy", _nrt=False)
def surface(a, h, rs, slope, P, du, dv):
    best = math.inf
    kb = 0
    for k in range(P.shape[0]):
        w = (P[k, 3] - P[k, 0] * du - P[k, 1] * dv) / P[k, 2]
        if w < best:
            best = w
            kb = k
    return best, P[kb, 0], P[kb, 1], P[kb, 2]
