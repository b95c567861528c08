"""Light tracing beside the paths from the eye (`tracer.transport.radiance`): photons from the lights joined to the
eye at their diffuse vertices, for the light paths from the eye miss or find badly.

Light tracing (`trace_light`, where `light_paths` says the scene needs it: a specular surface, or a collimated or
rayfile light). Photons leave the traced lights in proportion to their flux and follow the scene by `scatter`, as the
forward photons do. Each diffuse vertex x of an eligible photon is joined to the eye (`join_eye`, pbrt-v3's
`LightTracer` with the camera's `Sample_Wi`): the photon's flux Φ × ρ/π × cosθ_x / d² × W goes to the view that sees x
unoccluded, W the view's importance (1/Ω for a meter's cone, 1/(cos³θ × film area) for the pixel x projects to, through
a lens point where the camera has a lens). Eligible: every photon of a collimated or rayfile light (no shadow ray
reaches them); a photon of a point-like or area light once its first bounce was specular. So the two strategies split
the paths: paths from the eye take those whose vertex next to the light scatters diffusely (the shadow ray, and, for an
area light, the BSDF sample that hits it, by MIS), light tracing those whose vertex next to the light scatters
specularly and whose vertex next to the eye diffusely; a photon whose first bounce is diffuse ends there, and a path
from the eye whose first vertex was diffuse adds nothing where it meets a traced area light after a specular vertex
(`traced_area`: light tracing has it). Both are unbiased, and a batch's value of a view is their sum, so the batch
means' standard error holds for both. An area light seen from a diffuse wall only through glass (an LED behind a lamp's
lens) is light tracing's: the shadow ray stops at the glass, and a BSDF sample finds the small emitter rarely. Where the
join to the eye itself is blocked by glass, it goes through flat parallel faces by the path Snell's law allows
(`tracer.transport.through_flat`: a reflector sheet or a printed dot under a light guide, seen through it), and a path
from the eye that crossed those faces first leaves that path to light tracing too. Area lights are traced only where a
pilot of photons reaches the views (`light_paths`'s `area`): where no diffuse vertex can be joined to the eye, their
photons would only cost time. What neither finds: light from a point-like or collimated source whose vertex next to the
eye is specular too (a lamp, or its caustic, seen in a mirror or through glass); `through_specular` still flags the
views that may miss it. (An area light is found there, by paths from the eye hitting it.)

The radiance kernel's counters (`COUNTERS`) live here, as both halves count into them.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from tracer.accel.spawn import offset_ray_origin
from tracer.accel.traverse import any_with_stacks, closest_with_stacks
from tracer.effects import BASELINE
from tracer.jit import njit
from tracer.optics.frames import find_in_cdf
from tracer.optics.lights import sample_emission
from tracer.optics.lights.base import AREA_EMITTER, DELTA_DIRECTION
from tracer.optics.lights.dispatch import LIGHT_FLAGS
from tracer.optics.surfaces.base import CONTINUES, DIFFUSE, STACK_FULL, arrival_normal, reflect_specular
from tracer.optics.surfaces.dispatch import scatter, surface_albedo, surface_flags
from tracer.rng import path_key, uniform
from tracer.transport.through_flat import through_flat_at

MAX_BOUNCES = 10_000    # a longer path (from the eye or from a light) is cut and counted
COUNTERS = ("rejected", "truncated", "stack_overflow", "caustic_paths", "light_paths", "light_splats", "view_rays",
            "light_rays", "left_to_light_tracing")
# view_rays, light_rays: the closest hits and shadow rays each strategy cast (its work); left_to_light_tracing: the
# paths from the eye that met a traced area light and left it to light tracing (`trace_view`)
C_REJECTED, C_TRUNCATED, C_STACK, C_CAUSTIC, C_LIGHT_PATHS, C_LIGHT_SPLATS, C_VIEW_RAYS, C_LIGHT_RAYS, C_LEFT = range(9)
LIGHT_RR_WEIGHT = 0.01   # a light path below this fraction of its initial flux plays Russian roulette (`forward`)


class LightPaths(NamedTuple):
    """The light-tracing half of a query (`light_paths`): photons from the lights paths from the eye cannot reach
    through a specular surface, joined to the eye at diffuse vertices (module docstring, "Light tracing").

    cdf (n_lights,): the cumulative probability of emitting from each light, ∝ its flux over the lights traced
    from (a light not traced has probability 0). always (n_lights,) int64: 1 for a light no shadow ray reaches
    (collimated, rayfile): its photons join the eye at every diffuse vertex; 0 for a point-like or area light: only
    the photons whose first bounce was specular do. flux (1,): the traced lights' flux (lm). photons (1,) int64:
    photons a batch (0: no light tracing). width (1,) int64: a camera's columns (its pixels a row-major grid of
    the same eye, film and lens); 0 for meters (cones), each joined on its own. flat (1,) int64: 1 where the scene
    has glass, so that a diffuse vertex is joined through its flat faces where the straight segment is blocked
    (`tracer.transport.through_flat`), and a path from the eye that crossed them first to a vertex so joined neither
    counts as seeing through a specular chain nor, for a traced area light, keeps that path. join_at (1,) int64:
    `through_flat`'s address in the process that runs the kernel (`through_flat.bind`; 0 until bound).
    """

    cdf: np.ndarray
    always: np.ndarray
    flux: np.ndarray
    photons: np.ndarray
    width: np.ndarray
    flat: np.ndarray
    join_at: np.ndarray


#: trace area lights too where the scene has a specular surface and a pilot says light tracing reaches the views
#: (False: paths from the eye alone find them, as before; `bench/bench_area_lights.py` compares the two)
AREA_LIGHT_TRACING = True


def no_light_paths(n_lights: int) -> LightPaths:
    """A `LightPaths` that traces nothing."""
    n = max(n_lights, 1)
    return LightPaths(np.ones(n), np.zeros(n, np.int64), np.zeros(1), np.zeros(1, np.int64), np.zeros(1, np.int64),
                      np.zeros(1, np.int64), np.zeros(1, np.int64))


def light_paths(L, effects, photons: int, width: int, area: bool = False, others: bool = True) -> LightPaths:
    """The `LightPaths` of a query: light tracing where the scene has something paths from the eye miss, or find
    badly: from a collimated or rayfile light (no shadow ray reaches it), and, where the scene has a specular surface,
    from every point-like light (a caustic) and, where `area`, every area light (one behind glass, which no shadow
    ray sees through: `tracer.transport.rounds.area_light_pilot` decides); `others` False: the area lights alone.
    `L`: the packed lights (`LightArrays`); `effects`: the scene's (`tracer.effects`); `photons` a batch; `width`: a
    camera's columns, 0 for meters."""
    flags = LIGHT_FLAGS[np.asarray(L.kind)]
    n = len(flags)
    pick = np.diff(np.concatenate([[0.0], np.asarray(L.cdf, float)])) * float(L.flux_total[0])
    specular = bool(set(effects) - {BASELINE})
    is_area = flags & AREA_EMITTER != 0
    traced = (pick > 0.0) & ((is_area & (area and specular and AREA_LIGHT_TRACING)) | (~is_area & others))
    always = (flags & DELTA_DIRECTION != 0).astype(np.int64)   # no shadow ray reaches it
    if n == 0 or not traced.any() or not (np.any(always[traced]) or specular):
        return no_light_paths(n)
    flux = float(pick[traced].sum())
    cdf = np.cumsum(np.where(traced, pick, 0.0)) / flux
    cdf[-1] = 1.0
    flat = np.array(["fresnel" in effects], np.int64)
    return LightPaths(cdf, always, np.array([flux]), np.array([photons], np.int64), np.array([width], np.int64), flat,
                      np.zeros(1, np.int64))


@njit(cache=True, error_model="numpy", _nrt=False)
def traced_area(P, E, inst):
    """Whether instance `inst` emits for an area light that `P` traces from (`light_paths`; with no photons a batch,
    the pilot's count of what would be left to light tracing, `tracer.transport.rounds.area_light_pilot`)."""
    j = E.light[inst]
    if j < 0:
        return False
    return P.cdf[j] - (P.cdf[j - 1] if j > 0 else 0.0) > 0.0


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def lens_point(V, u0, u1):
    """A camera's eye point: its pinhole, or with a thin lens the point `u0`, `u1` pick, uniform on the lens."""
    ox, oy, oz = V.o[0, 0], V.o[0, 1], V.o[0, 2]
    if V.lens[0] <= 0.0:
        return ox, oy, oz
    r = V.lens[0] * math.sqrt(u0)
    phi = 2.0 * math.pi * u1
    ia = 1.0 / math.sqrt(V.a[0, 0] ** 2 + V.a[0, 1] ** 2 + V.a[0, 2] ** 2)
    ib = 1.0 / math.sqrt(V.b[0, 0] ** 2 + V.b[0, 1] ** 2 + V.b[0, 2] ** 2)
    ca, sb = r * math.cos(phi) * ia, r * math.sin(phi) * ib
    return (ox + ca * V.a[0, 0] + sb * V.b[0, 0], oy + ca * V.a[0, 1] + sb * V.b[0, 1],
            oz + ca * V.a[0, 2] + sb * V.b[0, 2])


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def film_pixel(V, P, ex, ey, ez, sx, sy, sz):
    """The pixel of a camera that sees along -s from its eye point E (s: from the point seen, or a point on the ray to
    it, to E): the one holding the film point (unit distance along the axis) whose pinhole ray meets the ray E → point
    on the plane of focus (for a pinhole: the ray itself); -1 off the film."""
    along = -(sx * V.axis[0, 0] + sy * V.axis[0, 1] + sz * V.axis[0, 2])   # (x − eye) · axis
    if along <= 0.0:
        return -1
    ox, oy, oz = V.o[0, 0], V.o[0, 1], V.o[0, 2]
    if V.lens[0] > 0.0:
        k = V.focus[0] / along
        f = 1.0 / V.focus[0]
        fx = (ex - k * sx - ox) * f
        fy = (ey - k * sy - oy) * f
        fz = (ez - k * sz - oz) * f
    else:
        fx, fy, fz = -sx / along, -sy / along, -sz / along
    fx, fy, fz = fx - V.c[0, 0], fy - V.c[0, 1], fz - V.c[0, 2]
    a2 = V.a[0, 0] ** 2 + V.a[0, 1] ** 2 + V.a[0, 2] ** 2
    b2 = V.b[0, 0] ** 2 + V.b[0, 1] ** 2 + V.b[0, 2] ** 2
    s = (fx * V.a[0, 0] + fy * V.a[0, 1] + fz * V.a[0, 2]) / a2
    t = (fx * V.b[0, 0] + fy * V.b[0, 1] + fz * V.b[0, 2]) / b2
    width = P.width[0]
    height = V.kind.shape[0] // width
    if not (0.0 <= s < width and 0.0 <= t < height):
        return -1
    return int(t) * width + int(s)


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def join_eye(sa, M, V, P, lum, x, y, z, nx, ny, nz, value, u0, u1, med, depth, chain, stack, tstack):
    """Join a diffuse vertex x (off its surface; n its unit normal on the side the photon came from) to the views'
    eyes: `value` = the photon's flux × ρ/π (lm/sr, the radiant intensity per unit projected area that its diffuse
    reflection gives each direction × area) adds value × cosθ_x / d² × W to each view that sees x unoccluded, W the
    view's importance: 1/Ω for a cone that holds the direction, 1/(cos³θ × film area) for the pixel it falls in
    (θ from the camera axis; with a thin lens through the lens point u0, u1 picks, uniform on the lens). Where
    `P.flat` says the scene has glass, a segment the glass blocks is joined through it where it crosses flat, parallel
    faces only (`tracer.transport.through_flat`: cosθ_x T / J in place of cosθ_x / d², W that of the refracted ray
    at the eye; `chain` its scratch, `through_flat.CHAIN_SHAPE`). Returns the number of views joined."""
    joined = 0
    for q in range(V.kind.shape[0] if P.width[0] == 0 else 1):   # a camera: its views are one grid, from one eye
        if P.width[0] > 0:
            ex, ey, ez = lens_point(V, u0, u1)
        else:
            ex, ey, ez = V.o[q, 0], V.o[q, 1], V.o[q, 2]
        sx, sy, sz = ex - x, ey - y, ez - z     # from the vertex to the eye (or the lens point)
        d2 = sx * sx + sy * sy + sz * sz
        dist = math.sqrt(d2)
        cos_x = (sx * nx + sy * ny + sz * nz) / dist
        view = _view_of(V, P, q, ex, ey, ez, sx, sy, sz) if cos_x > 0.0 else -1
        if view < 0 and P.flat[0] == 0:   # neither the straight segment nor glass (none) joins x here
            continue
        if not any_with_stacks(sa, x, y, z, sx, sy, sz, 1.0, stack, tstack):
            if view >= 0:
                lum[view] += value * cos_x / d2 / _per_importance(V, P, view, sx, sy, sz)
                joined += 1
            continue
        if P.flat[0] == 0:
            continue
        faces, px, py, pz, factor = through_flat_at(P.join_at, 0, (sa, M, x, y, z, nx, ny, nz, ex, ey, ez, med, depth,
                                                                    chain, stack, tstack))
        if faces == 0:
            continue
        sx, sy, sz = ex - px, ey - py, ez - pz    # the refracted ray that reaches the eye, from the face
        view = _view_of(V, P, q, ex, ey, ez, sx, sy, sz)
        if view >= 0:
            lum[view] += value * factor / _per_importance(V, P, view, sx, sy, sz)
            joined += 1
    return joined


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _view_of(V, P, q, ex, ey, ez, sx, sy, sz):
    """The view that sees along -s from its eye point E: the camera's pixel, or meter q where its cone holds the
    direction; -1 for none."""
    if P.width[0] > 0:
        return film_pixel(V, P, ex, ey, ez, sx, sy, sz)
    cos_c = -(sx * V.axis[q, 0] + sy * V.axis[q, 1] + sz * V.axis[q, 2]) / math.sqrt(sx * sx + sy * sy + sz * sz)
    return q if cos_c >= V.cos_max[q] and cos_c > 0.0 else -1


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _per_importance(V, P, view, sx, sy, sz):
    """1/W of the view for a ray arriving along -s: cos³θ × film area for a pixel (θ from the axis), Ω for a cone."""
    if P.width[0] > 0:
        cos_c = -(sx * V.axis[0, 0] + sy * V.axis[0, 1] + sz * V.axis[0, 2]) / math.sqrt(sx * sx + sy * sy + sz * sz)
        return cos_c ** 3 * V.size[view]
    return V.size[view]


@njit(cache=True, error_model="numpy", _nrt=False)
def trace_light(sa, M, L, V, P, seed, batch, first, lum, counters, med, pol, chain, stack, tstack):
    """Light tracing, one batch: `P.photons` photons from the lights of `P.cdf` through the scene (`scatter`, as
    the forward photons go), each diffuse vertex of an eligible photon joined to the eyes (`join_eye`), the sum
    divided by the photon count added to lum (k,). Eligible: a photon of a light in `P.always`, or one whose first
    bounce was specular (the rest, whose first bounce is diffuse, are next-event estimation's: they end there).
    Keys: path_key(seed, batch, first + i), past the paths from the eye."""
    n = P.photons[0]
    nl = P.cdf.shape[0]
    for i in range(n):
        key = path_key(seed, batch, first + i)
        j = find_in_cdf(P.cdf, 0, nl, uniform(key, 0))
        pj = P.cdf[j] - (P.cdf[j - 1] if j > 0 else 0.0)
        if pj <= 0.0:
            continue
        ox, oy, oz, dx, dy, dz, f, on_surface, nx, ny, nz = sample_emission(
            L, j, uniform(key, 1), uniform(key, 2), uniform(key, 3), uniform(key, 4), uniform(key, 5))
        w = P.flux[0] * f / n     # lm: the photon's share of the traced lights' flux
        if on_surface:
            ox, oy, oz = offset_ray_origin(ox, oy, oz, nx, ny, nz, dx, dy, dz)
        if not (math.isfinite(w) and math.isfinite(dx + dy + dz) and math.isfinite(ox + oy + oz)) or w <= 0.0:
            continue
        counters[C_LIGHT_PATHS] += 1
        w_init = w
        eligible = P.always[j] != 0
        dim = 6
        depth = 0
        truncated = True
        for bounce in range(MAX_BOUNCES):
            t, inst, prim, hu, hv, ngx, ngy, ngz = closest_with_stacks(sa, ox, oy, oz, dx, dy, dz, math.inf, stack,
                                                                       tstack)
            counters[C_LIGHT_RAYS] += 1
            if inst < 0:
                truncated = False
                break
            px, py, pz = ox + t * dx, oy + t * dy, oz + t * dz
            fx, fy, fz = arrival_normal(ngx, ngy, ngz, dx, dy, dz)
            rho = surface_albedo(sa, M, inst, prim)
            if eligible and rho > 0.0:
                sx, sy, sz = offset_ray_origin(px, py, pz, ngx, ngy, ngz, fx, fy, fz)
                counters[C_LIGHT_RAYS] += 1 if P.width[0] > 0 else V.kind.shape[0]
                counters[C_LIGHT_SPLATS] += join_eye(sa, M, V, P, lum, sx, sy, sz, fx, fy, fz, w * rho / math.pi,
                                                     uniform(key, dim), uniform(key, dim + 1), med, depth, chain,
                                                     stack, tstack)
                dim += 2
            status, ux, uy, uz, f, depth, dim = scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med,
                                                        depth, key, dim, 0.0, pol)
            if status == STACK_FULL:
                counters[C_STACK] += 1
            if status != CONTINUES:
                truncated = False
                break
            if bounce == 0 and not eligible:
                # the first bounce: specular (a mirror, glass, the specular lobe of a mix) or diffuse
                if surface_flags(sa, M, inst, prim) == DIFFUSE:
                    truncated = False
                    break
                if rho > 0.0 and ux * fx + uy * fy + uz * fz > 0.0:
                    mx, my, mz = reflect_specular(sa, inst, prim, hu, hv, dx, dy, dz, fx, fy, fz)
                    if not (mx == ux and my == uy and mz == uz):
                        truncated = False
                        break
                eligible = True
            w *= f
            dx, dy, dz = ux, uy, uz
            ox, oy, oz = offset_ray_origin(px, py, pz, ngx, ngy, ngz, dx, dy, dz)
            if w < LIGHT_RR_WEIGHT * w_init:   # Russian roulette: unbiased
                q = w / (LIGHT_RR_WEIGHT * w_init)
                if uniform(key, dim) >= q:
                    truncated = False
                    break
                dim += 1
                w /= q
        if truncated:
            counters[C_TRUNCATED] += 1
