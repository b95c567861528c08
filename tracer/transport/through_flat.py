"""Joining a diffuse point to an eye through flat glass: the one path Snell's law allows through parallel faces.

Light tracing joins each diffuse vertex x to the eye with a straight shadow ray (`tracer.transport.light_tracing`),
which stops at glass: a backlight's reflector sheet under a light guide, or a printed dot on its underside, lit by
light the guide traps, is never joined to a camera above it, and paths from the eye find the LED behind the guide's
edge only by chance. Where the straight segment from x to the eye E crosses up to `MAX_FACES` flat faces, all
parallel (a guide's bottom and top, a film above it), each between a solid and air, the one refracted path
x → S₁ → … → S_K → E exists (Hanika et al. 2015, manifold next-event estimation, for planar interfaces): the layers
between the planes, of thickness d_k and index n_k along the faces' normal, keep p = n_k sin θ_k (Snell), and p is
where the path's run along the faces, X(p) = Σ d_k tan θ_k, equals the run from x to E (monotone in p: bisection).
A pencil of rays leaving x into the solid angle dΩ crosses the area dA⊥ = J dΩ across its axis at E, with

    J = (Σ d_k (n₀/n_k) / cos θ_k) · cos θ_K · (Σ d_k n₀ cos θ₀ / (n_k cos³ θ_k))

(its sagittal and meridional spread; no glass, J = d²), so the vertex of radiant intensity I gives E the irradiance
I T / J, T the product of the unpolarised Fresnel transmittances (1 − R̄, as paths from the eye refract) at the faces.
The path's own segments are cast, face to face, so that anything in its way stops the join.

A face is *flat* here (`flat_face`) where its hit is on a plain triangle (no element's feature, no tabulated support)
of a smooth `dielectric` whose shading normal at the hit is the geometric one. A path from the eye that crosses K
such faces first and then scatters diffusely (`same_join`: its vertex is joined back through the very point the path
crossed first) leaves a traced area light it meets after a specular vertex to light tracing, as one whose first
vertex is diffuse does: the two strategies keep splitting the paths between them, each path counted once.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import types

from tracer.accel.spawn import offset_ray_origin
from tracer.accel.traverse import any_with_stacks, closest_with_stacks
from tracer.jit import kind_table, njit
from tracer.optics.surfaces.base import specular_normal
from tracer.optics.surfaces.dielectric import ALPHA
from tracer.optics.surfaces.dispatch import DIELECTRIC, table_row
from tracer.optics.surfaces.fresnel import fresnel_dielectric

MAX_FACES = 4          # faces a join crosses at most (a guide's two, a film's two)
CHAIN_SHAPE = (MAX_FACES + 1, 3)   # the scratch `chain`: per layer [thickness along the normal, index, its face's
                                   # instance (the face that ends it)]
BISECTIONS = 64        # halvings of p's interval: to the last bit of a float64
SAME_POINT = 1e-6      # two points of a join agree within this fraction of its length
FLAT = 1e-9            # 1 − cos of the largest angle between two normals taken as one
GRAZING = 1e-6         # cos θ below this in a layer: no join (the pencil's spread diverges)


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def flat_face(sa, M, inst, prim, hu, hv, ngx, ngy, ngz):
    """Whether the hit (`inst`, `prim`, barycentrics, unit geometric normal) is on a flat face (module docstring)."""
    if prim < 0 or M.kind[inst] != DIELECTRIC or M.par[inst, ALPHA] > 0.0 or table_row(sa, inst, prim) >= 0:
        return False
    snx, sny, snz = specular_normal(sa, inst, prim, hu, hv, ngx, ngy, ngz)
    return snx * ngx + sny * ngy + snz * ngz >= 1.0 - FLAT


@njit(cache=True, error_model="numpy", _nrt=False)
def _layers(sa, M, x, y, z, ex, ey, ez, med, depth, chain, stack, tstack):
    """The faces the straight segment x → E crosses, into `chain`: ``(K, mx, my, mz)``, K their count (-1 where the
    segment cannot be joined through them: a face not flat, not parallel to the first, not between a solid and air,
    or more than `MAX_FACES`), m the unit normal of the first, turned towards E. Layer k's thickness (along m),
    index and the instance of the face ending it in ``chain[k]``; the last layer ends at E."""
    inside = med[0] if depth == 1 else -1      # the solid x is in (-1: air)
    if depth > 1:
        return -1, 0.0, 0.0, 0.0
    vx, vy, vz = ex - x, ey - y, ez - z
    ox, oy, oz = x, y, z
    mx, my, mz = 0.0, 0.0, 0.0
    level = 0.0   # how far along m the last face lies from x
    k = 0
    while True:
        t, inst, prim, hu, hv, gx, gy, gz = closest_with_stacks(sa, ox, oy, oz, ex - ox, ey - oy, ez - oz, 1.0,
                                                                stack, tstack)
        chain[k, 1] = M.par[inside, 0] if inside >= 0 else 1.0
        if inst < 0:   # E reached
            chain[k, 0] = (ex - x) * mx + (ey - y) * my + (ez - z) * mz - level if k > 0 else 0.0
            chain[k, 2] = -1.0
            return k, mx, my, mz
        if k == MAX_FACES or not flat_face(sa, M, inst, prim, hu, hv, gx, gy, gz):
            return -1, 0.0, 0.0, 0.0
        leaving = gx * vx + gy * vy + gz * vz > 0.0
        if (leaving and inst != inside) or (not leaving and inside >= 0):
            return -1, 0.0, 0.0, 0.0
        if k == 0:
            mx, my, mz = (gx, gy, gz) if leaving else (-gx, -gy, -gz)
        elif abs(gx * mx + gy * my + gz * mz) < 1.0 - FLAT:
            return -1, 0.0, 0.0, 0.0
        hx, hy, hz = ox + t * (ex - ox), oy + t * (ey - oy), oz + t * (ez - oz)
        at = (hx - x) * mx + (hy - y) * my + (hz - z) * mz
        chain[k, 0], chain[k, 2] = at - level, inst
        if not chain[k, 0] > 0.0:
            return -1, 0.0, 0.0, 0.0
        level = at
        inside = -1 if leaving else inst
        ox, oy, oz = offset_ray_origin(hx, hy, hz, gx, gy, gz, vx, vy, vz)
        k += 1


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _run(chain, n_layers, p):
    """X(p) = Σ d_k tan θ_k, sin θ_k = p / n_k."""
    run = 0.0
    for k in range(n_layers):
        s = p / chain[k, 1]
        run += chain[k, 0] * s / math.sqrt(1.0 - s * s)
    return run


@njit(cache=True, error_model="numpy", _nrt=False)
def through_flat(sa, M, x, y, z, nx, ny, nz, ex, ey, ez, med, depth, chain, stack, tstack):
    """The join of the point x (off its surface; n the unit normal of its side; in the solid ``med[0]`` where
    `depth` is 1, in air where 0) to the eye point E through the flat faces the straight segment crosses:
    ``(faces K, S_K (3): the last face's crossing, next to E, factor)``, factor = cos θ_x × T / J (1/m², what 1/d² is
    to a straight join: the vertex's flux × ρ/π × factor is the irradiance at E across the ray S_K → E). K = 0 where
    nothing joins x so (no face, or one that cannot be joined through, or a segment of the path blocked)."""
    no = (0, 0.0, 0.0, 0.0, 0.0)
    faces, mx, my, mz = _layers(sa, M, x, y, z, ex, ey, ez, med, depth, chain, stack, tstack)
    if faces <= 0:
        return no
    n_layers = faces + 1
    wx, wy, wz = ex - x, ey - y, ez - z
    along = wx * mx + wy * my + wz * mz
    wx, wy, wz = wx - along * mx, wy - along * my, wz - along * mz      # the run from x to E, along the faces
    big_x = math.sqrt(wx * wx + wy * wy + wz * wz)
    p_max = chain[0, 1]
    for k in range(1, n_layers):
        p_max = min(p_max, chain[k, 1])
    lo, hi = 0.0, p_max
    if big_x > 0.0:
        for _ in range(BISECTIONS):
            mid = 0.5 * (lo + hi)
            if _run(chain, n_layers, mid) < big_x:
                lo = mid
            else:
                hi = mid
    p = 0.5 * (lo + hi) if big_x > 0.0 else 0.0
    hx, hy, hz = (wx / big_x, wy / big_x, wz / big_x) if big_x > 0.0 else (0.0, 0.0, 0.0)
    # the crossings, face by face, each segment cast; sums for J and T on the way
    sag = 0.0        # Σ d_k (n₀/n_k) / cos θ_k
    mer = 0.0        # Σ d_k n₀ cos θ₀ / (n_k cos³ θ_k)
    transmit = 1.0
    n0 = chain[0, 1]
    cos0 = math.sqrt(1.0 - (p / n0) ** 2)
    ax, ay, az = x, y, z                  # the segment's start
    sx, sy, sz = x, y, z                  # the crossing it ends at
    cos_x = 0.0
    cos_prev = cos0
    for k in range(n_layers):
        s = p / chain[k, 1]
        c = math.sqrt(1.0 - s * s)
        if c < GRAZING:
            return no
        d = chain[k, 0]
        sag += d * (n0 / chain[k, 1]) / c
        mer += d * n0 * cos0 / (chain[k, 1] * c * c * c)
        if k > 0:   # the face between layers k − 1 and k
            transmit *= 1.0 - fresnel_dielectric(cos_prev, chain[k - 1, 1], chain[k, 1])
        cos_prev = c
        if k == faces:
            break
        run = d * s / c
        sx, sy, sz = sx + d * mx + run * hx, sy + d * my + run * hy, sz + d * mz + run * hz
        if k == 0:
            length = math.sqrt((sx - x) ** 2 + (sy - y) ** 2 + (sz - z) ** 2)
            cos_x = ((sx - x) * nx + (sy - y) * ny + (sz - z) * nz) / length
            if cos_x <= 0.0:
                return no
        t, inst, prim, hu, hv, gx, gy, gz = closest_with_stacks(sa, ax, ay, az, sx - ax, sy - ay, sz - az,
                                                                1.0 + SAME_POINT, stack, tstack)
        if inst != int(chain[k, 2]) or abs(t - 1.0) > SAME_POINT or abs(gx * mx + gy * my + gz * mz) < 1.0 - FLAT \
                or not flat_face(sa, M, inst, prim, hu, hv, gx, gy, gz):
            return no
        ax, ay, az = offset_ray_origin(sx, sy, sz, gx, gy, gz, ex - sx, ey - sy, ez - sz)
    if any_with_stacks(sa, ax, ay, az, ex - ax, ey - ay, ez - az, 1.0, stack, tstack):
        return no
    spread = sag * cos_prev * mer
    return faces, sx, sy, sz, cos_x * transmit / spread


def _join_signature(head):
    """The argument types `through_flat` is compiled for, from those of the scene's and the materials' tuples."""
    f8 = types.float64
    return (head[0], head[1], *[f8] * 9, types.int64[::1], types.int64, types.float64[:, ::1], types.int64[::1],
            types.float64[::1])


#: `through_flat` called at its address (`tracer.jit.kind_table`): compiled on its own, once, in a process whose
#: query needs it (`bind`), and in no kernel. Compiled into the luminance kernel it added 7.4 s to its cold compile
#: (25.3 → 32.7 s); so 25.7 s, and a first query that joins through glass waits 6.6 s more, once
#: (`bench/bench_luminance_compile.py`, empty caches, 2026-12-08)
through_flat_at = kind_table("through_flat_at", {0: through_flat}, _join_signature,
                             types.Tuple((types.int64, *[types.float64] * 4)))
_TABLES: dict = {}


def bind(sa, M) -> np.ndarray:
    """A table holding `through_flat`'s address in this process for the types of `sa` and `M` (compiled, or loaded
    from numba's cache, on the first call): what the luminance kernel needs before it runs where its `LightPaths`
    join through glass (`tracer.backends.run_kernel`)."""
    head = (numba.typeof(sa), numba.typeof(M))
    bound = _TABLES.setdefault(head, np.zeros(1, np.int64))
    through_flat_at.bind(bound, head, [0])
    return bound


@njit(cache=True, error_model="numpy", _nrt=False)
def same_join(sa, M, x, y, z, nx, ny, nz, ex, ey, ez, faces, sx, sy, sz, med, depth, chain, stack, tstack, join_at):
    """Whether light tracing joins the diffuse vertex x back to the eye E through the `faces` flat faces a path from
    E crossed first, crossing the last of them at S (the path's first hit from E): then that path is light
    tracing's (module docstring). `join_at`: `through_flat`'s address (`bind`)."""
    k, px, py, pz, _ = through_flat_at(join_at, 0, (sa, M, x, y, z, nx, ny, nz, ex, ey, ez, med, depth, chain, stack,
                                                    tstack))
    span = math.sqrt((ex - x) ** 2 + (ey - y) ** 2 + (ez - z) ** 2)
    return k == faces and math.sqrt((px - sx) ** 2 + (py - sy) ** 2 + (pz - sz) ** 2) <= SAME_POINT * span
