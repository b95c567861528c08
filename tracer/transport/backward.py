"""Backward tracing from the query points with next-event estimation (Radiance's way, with an error bar).

For a query patch (a disk around a query point, or a grid cell) with unit normal n, the illuminance
averaged over the patch is E = ∫ L(x, ω) cosθ dω, averaged over x. A path starts at a uniform point
x of the patch and

- adds the direct illuminance at x from one light chosen in proportion to its flux (next-event
  estimation: the light's `connect` gives one sample of its illuminance at x and the shadow ray to
  the point it sampled, see `tracer.optics.lights.base`), divided by the choice probability;
- leaves x in a cosine-distributed direction (pdf cosθ/π, so the estimator of E is π L: the π
  cancels against the Lambertian BRDF ρ/π of the next surface, leaving a path weight that is
  multiplied by ρ at each diffuse bounce);
- at each Lambertian hit y adds weight × (direct illuminance at y from one chosen light) — the
  reflected radiance there is ρ/π × E(y) — and continues in a new cosine direction.

Emission is counted only by next-event estimation, never when a path happens to hit an emitter,
so nothing is counted twice. Russian roulette after `RR_DEPTH` bounces survives with the path
weight (≤ 1) as probability and divides by it: unbiased.

Limits (why `Simulation` chooses the forward estimator for such scenes): point-like and collimated
sources cannot be reached through mirrors or glass by a shadow ray, so only scenes whose surfaces are
purely diffuse (each surface kind's `diffuse_only`; their albedo from `tracer.optics.surfaces.dispatch.albedo`)
and whose lights can be connected to (a light kind's `FLAGS` without a delta direction, sampled by
`light_connect`) are traced backward.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from tracer.accel.spawn import offset_ray_origin
from tracer.accel.traverse import any_with_stacks, closest_with_stacks, new_stacks
from tracer.jit import njit
from tracer.optics.frames import onb, sample_cosine
from tracer.optics.lights import light_connect, pick_light
from tracer.optics.surfaces.dispatch import surface_albedo
from tracer.rng import path_key, uniform

RR_DEPTH = 3
MAX_BOUNCES = 10_000

COUNTERS = ("rejected", "truncated")


class QueryArrays(NamedTuple):
    """Query patches.

    kind (k,) int64: 0 disk (centre + r(x a + y b), (x, y) uniform in the unit disk), 1 parallelogram
    (origin + s a + t b, s, t uniform in [0, 1]); o (k, 3) centre or origin, already moved off any
    surface along n; a, b (k, 3) the patch's axes (disk: orthonormal × radius); n (k, 3) unit normal.
    """

    kind: np.ndarray
    o: np.ndarray
    a: np.ndarray
    b: np.ndarray
    n: np.ndarray


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def direct_illuminance(sa, L, x, y, z, nx, ny, nz, u0, u1, u2, u3, stack, tstack):
    """Estimate of the direct illuminance (lx) at point x on a surface with unit normal n, from one light.

    x must already be off any surface (shadow rays start there). The light is picked in proportion to
    its flux (u0) and asked for one sample of its illuminance at x (u1, u2, u3) and the shadow ray that
    decides whether it arrives.
    """
    j, pj = pick_light(L, u0)
    if pj <= 0.0:
        return 0.0
    e, sx, sy, sz, t_max = light_connect(L, j, x, y, z, nx, ny, nz, u1, u2, u3)
    if e <= 0.0:
        return 0.0
    if any_with_stacks(sa, x, y, z, sx, sy, sz, t_max, stack, tstack):
        return 0.0
    return e / pj


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def trace_path(sa, M, L, Q, q, key, counters, stack, tstack):
    """One backward path from query patch q: an unbiased estimate of its mean illuminance (lx)."""
    if Q.kind[q] == 0:
        r = math.sqrt(uniform(key, 0))
        phi = 2.0 * math.pi * uniform(key, 1)
        s, t = r * math.cos(phi), r * math.sin(phi)
    else:
        s, t = uniform(key, 0), uniform(key, 1)
    x = Q.o[q, 0] + s * Q.a[q, 0] + t * Q.b[q, 0]
    y = Q.o[q, 1] + s * Q.a[q, 1] + t * Q.b[q, 1]
    z = Q.o[q, 2] + s * Q.a[q, 2] + t * Q.b[q, 2]
    nx, ny, nz = Q.n[q, 0], Q.n[q, 1], Q.n[q, 2]
    e = direct_illuminance(sa, L, x, y, z, nx, ny, nz, uniform(key, 2), uniform(key, 3), uniform(key, 4),
                           uniform(key, 5), stack, tstack)
    dx, dy, dz = sample_cosine(nx, ny, nz, uniform(key, 6), uniform(key, 7))
    dim = 8
    w = 1.0
    for bounce in range(MAX_BOUNCES):
        t_hit, inst, prim, hu, hv, ngx, ngy, ngz = closest_with_stacks(sa, x, y, z, dx, dy, dz, math.inf, stack,
                                                                       tstack)
        if inst < 0:
            break
        w *= surface_albedo(sa, M, inst, prim)   # only purely diffuse kinds reach here (Simulation.backward_applies)
        if w <= 0.0:
            break
        px, py, pz = x + t_hit * dx, y + t_hit * dy, z + t_hit * dz
        fx, fy, fz = ngx, ngy, ngz
        if dx * fx + dy * fy + dz * fz > 0.0:
            fx, fy, fz = -fx, -fy, -fz
        sx, sy, sz = offset_ray_origin(px, py, pz, ngx, ngy, ngz, fx, fy, fz)
        e += w * direct_illuminance(sa, L, sx, sy, sz, fx, fy, fz, uniform(key, dim), uniform(key, dim + 1),
                                    uniform(key, dim + 2), uniform(key, dim + 3), stack, tstack)
        dx, dy, dz = sample_cosine(fx, fy, fz, uniform(key, dim + 4), uniform(key, dim + 5))
        dim += 6
        x, y, z = sx, sy, sz
        if bounce + 1 >= RR_DEPTH:
            q_survive = min(1.0, w)
            if uniform(key, dim) >= q_survive:
                break
            dim += 1
            w /= q_survive
    else:
        counters[1] += 1
    if not math.isfinite(e):
        counters[0] += 1
        return 0.0
    return e


@njit(cache=True, error_model="numpy", nogil=True)
def backward_batches(sa, M, L, Q, seed, batch0, n_batches, paths):
    """Batches batch0 … batch0+n_batches−1, each `paths` paths per query patch.

    Returns (lux (n_batches, k) float64: each batch's estimate per patch; counters (n_batches, 2) int64).
    Serial and without the GIL, like `tracer.transport.forward.forward_batches`.
    """
    k = Q.kind.shape[0]
    out = np.zeros((n_batches, k))
    cnt = np.zeros((n_batches, len(COUNTERS)), np.int64)
    for b in range(n_batches):
        stack, tstack = new_stacks()
        backward_batch(sa, M, L, Q, seed, batch0 + b, paths, out[b], cnt[b], stack, tstack)
    return out, cnt


@njit(cache=True, error_model="numpy", _nrt=False)
def backward_batch(sa, M, L, Q, seed, batch, paths, lux, counters, stack, tstack):
    """Batch `batch`: `paths` paths per query patch; each patch's estimate (lx) into lux (k,), the counters
    into counters (2,). Allocates nothing (the stacks are the caller's): `backward_batches` runs it batch after
    batch, `tracer.gpu.transport` one batch per CUDA thread."""
    for q in range(Q.kind.shape[0]):
        acc = 0.0
        for i in range(paths):
            key = path_key(seed, batch, q * paths + i)
            acc += trace_path(sa, M, L, Q, q, key, counters, stack, tstack)
        lux[q] = acc / paths


def disk_queries(centers: np.ndarray, normals: np.ndarray, radius: float) -> QueryArrays:
    """Disk patches of `radius` around `centers` (k, 3) (already offset) with unit `normals` (k, 3)."""
    k = len(centers)
    a = np.zeros((k, 3))
    b = np.zeros((k, 3))
    for i in range(k):
        t, bb = onb(*normals[i])
        a[i], b[i] = np.asarray(t) * radius, np.asarray(bb) * radius
    return QueryArrays(np.zeros(k, np.int64), np.ascontiguousarray(centers, np.float64), a, b,
                       np.ascontiguousarray(normals, np.float64))
