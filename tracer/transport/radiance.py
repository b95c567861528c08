"""Paths from the eye: the luminance (cd/m² = lm/(m² sr)) a meter or a camera pixel sees, with an error bar.

A view (a luminance meter's cone, a camera pixel) is a set of directions from one eye point. Its luminance is the
mean of the radiance L(o, ω) over the view: uniform in solid angle over a meter's cone, uniform over the pixel's
area on the film (at unit distance along the camera axis) for a pixel. A path starts at the eye in one direction
drawn so, and follows the scene:

- at a surface that emits (an area light's instance, hit on its front side) it adds the emitted radiance M/π,
  weighted by multiple importance sampling (power heuristic, Veach 1997) against the light sampling below where
  the direction was drawn from a diffuse lobe, in full where it came from the eye or a specular chain;
- at a surface with a diffuse part (its albedo ρ, `tracer.optics.surfaces.dispatch.albedo`) it adds ρ/π × the
  illuminance from one light picked in proportion to its flux (`light_connect`, next-event estimation, divided by
  the pick's probability), with the MIS weight where the light has area (point-like lights: weight 1);
- a Lambertian surface then sends the path on in a cosine-distributed direction with its weight × ρ; any other
  surface (mirror, dielectric, the two lobes of a mix, thin elements) is asked of `scatter`, the same function the
  photons use: it reflects, refracts (keeping the stack of solids the path is inside) or absorbs, choosing with
  the probability of each outcome, so the weight stays;
- after `RR_DEPTH` diffuse bounces Russian roulette ends a path with probability 1 − weight (and divides the
  survivors by the survival probability): unbiased.

Point-like lights (point, spot, goniometric) seen directly from the eye are added exactly, once per view and
batch: E⊥ / Ω for a meter whose cone holds the light (Ω the cone's solid angle), E⊥ / (cos³θ × film area) for the
pixel the light falls in (E⊥ = I/d², unoccluded). What paths from the eye cannot find is light that reaches the
eye, or a diffuse point, from a point-like or collimated source through a specular chain only (a lamp seen in a
mirror or through glass, a caustic on a wall): the kernel counts, per view, the share of paths whose view ray went
on through a specular surface before any diffuse one (`through_specular`), and the paths that met a specular
surface after a diffuse one (counter `caustic_paths`); the sensor's answer states what is missing from them.

Light tracing (`tracer.transport.light_tracing`, where the scene needs it) runs beside them in the same batch and
takes the paths whose vertex next to the light scatters specularly and whose vertex next to the eye diffusely; a
path from the eye whose first vertex was diffuse adds nothing where it meets a traced area light after a specular
vertex (`traced_area`): light tracing has it.

Media (absorption or scattering inside solids), spectra and polarization are not followed here: the query refuses
scenes that need them (`tracer.simulate`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from tracer.accel.spawn import offset_ray_origin
from tracer.accel.traverse import any_with_stacks, closest_with_stacks, new_stacks
from tracer.jit import njit
from tracer.optics.frames import sample_cosine
from tracer.optics.lights import light_connect, pick_light
from tracer.optics.lights.area import emitting_triangles
from tracer.optics.lights.base import AREA_EMITTER, P_I0
from tracer.optics.lights.dispatch import flags_of, light_flags
from tracer.optics.polarization import N_POL
from tracer.optics.surfaces.base import CONTINUES, DIFFUSE, STACK_FULL, arrival_normal, reflect_specular
from tracer.optics.surfaces.dispatch import scatter, surface_albedo, surface_flags
from tracer.rng import path_key, uniform
from tracer.transport.light_tracing import (
    C_CAUSTIC,
    C_LEFT,
    C_REJECTED,
    C_STACK,
    C_TRUNCATED,
    C_VIEW_RAYS,
    COUNTERS,
    MAX_BOUNCES,
    trace_light,
    traced_area,
)
from tracer.transport.through_flat import CHAIN_SHAPE, flat_face, same_join

RR_DEPTH = 3            # diffuse bounces before Russian roulette (as `tracer.transport.backward`)
MEDIUM_DEPTH = 8        # nested solids a path may be inside
CONE, PIXEL = 0, 1      # view kinds


class ViewArrays(NamedTuple):
    """The views of a query (k of them).

    kind (k,) int64: `CONE` or `PIXEL`. o (k, 3): the eye (m). axis (k, 3): unit cone axis, or the camera's
    forward axis. a, b (k, 3): a cone's unit frame across its axis; a pixel's edges on the film (the plane at unit
    distance along `axis`), u and v. c (k, 3): a pixel's corner on the film (from the eye); unused for a cone.
    cos_max (k,): cos of a cone's half angle (1 for a pixel). size (k,): a cone's solid angle (sr), a pixel's film
    area |a × b|. lens (k,): a pixel's thin-lens radius (m; 0: a pinhole), the lens a disk across the axis at the eye
    (spanned by a and b). focus (k,): the focus distance along the axis (m; unused for a pinhole).
    """

    kind: np.ndarray
    o: np.ndarray
    axis: np.ndarray
    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    cos_max: np.ndarray
    size: np.ndarray
    lens: np.ndarray
    focus: np.ndarray


def pinhole(k: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``lens`` and ``focus`` of k views without a lens (meters, pinhole cameras)."""
    return np.zeros(k), np.ones(k)


class Emitters(NamedTuple):
    """Which instance emits: le (n_inst,) its radiance M/π on its front side (cd/m², 0: none); light (n_inst,) int64
    the area light it belongs to (−1: none), whose pick probability and area the MIS weight reads; tri0 (n_inst,)
    int64: where the instance's triangle mask starts in `emits` (−1: every triangle emits); emits (m,) uint8: 1 for
    a triangle that emits (an area light with `facing` or `faces`: its chosen triangles only)."""

    le: np.ndarray
    light: np.ndarray
    tri0: np.ndarray
    emits: np.ndarray


def emitters(light_bodies: list[dict], n_inst: int, scene) -> Emitters:
    """The `Emitters` of a simulation's (validated) light bodies over `scene` (a `tracer.Scene`): each area light's
    instances emit M/π, from the triangles its `facing` or `faces` chooses where it has one."""
    le = np.zeros(max(n_inst, 1))
    light = np.full(max(n_inst, 1), -1, np.int64)
    tri0 = np.full(max(n_inst, 1), -1, np.int64)
    masks = [np.zeros(1, np.uint8)]
    used = 1
    for j, body in enumerate(light_bodies):
        if flags_of(body) & AREA_EMITTER:
            for i in body["instances"]:
                le[int(i)] += float(body["exitance_lm_m2"]) / math.pi
                light[int(i)] = j
                mask = emitting_triangles(scene, int(i), body.get("facing"), body.get("faces"))
                if mask is not None:
                    tri0[int(i)] = used
                    masks.append(mask.astype(np.uint8))
                    used += len(mask)
    return Emitters(le, light, tri0, np.concatenate(masks))


@njit(cache=True, error_model="numpy", _nrt=False)
def emits(E, inst, prim):
    """Whether triangle `prim` of instance `inst` emits (an instance of an area light; a feature of an element,
    prim < 0, does not where the light chose its faces)."""
    o = E.tri0[inst]
    if o < 0:
        return True
    return prim >= 0 and E.emits[o + prim] != 0


@njit(cache=True, error_model="numpy", _nrt=False)
def view_direction(V, q, u0, u1):
    """A unit direction of view q: uniform in solid angle over a cone, uniform over a pixel's film area."""
    if V.kind[q] == CONE:
        c = 1.0 - u0 * (1.0 - V.cos_max[q])
        s = math.sqrt(max(0.0, 1.0 - c * c))
        phi = 2.0 * math.pi * u1
        cp, sp = s * math.cos(phi), s * math.sin(phi)
        dx = cp * V.a[q, 0] + sp * V.b[q, 0] + c * V.axis[q, 0]
        dy = cp * V.a[q, 1] + sp * V.b[q, 1] + c * V.axis[q, 1]
        dz = cp * V.a[q, 2] + sp * V.b[q, 2] + c * V.axis[q, 2]
    else:
        dx = V.c[q, 0] + u0 * V.a[q, 0] + u1 * V.b[q, 0]
        dy = V.c[q, 1] + u0 * V.a[q, 1] + u1 * V.b[q, 1]
        dz = V.c[q, 2] + u0 * V.a[q, 2] + u1 * V.b[q, 2]
    inv = 1.0 / math.sqrt(dx * dx + dy * dy + dz * dz)
    return dx * inv, dy * inv, dz * inv


@njit(cache=True, error_model="numpy", _nrt=False)
def lens_ray(V, q, dx, dy, dz, u0, u1):
    """A thin lens's ray for pixel direction d (unit): from a point uniform on the lens disk (radius V.lens[q], across
    the axis at the eye) through the point the pinhole ray meets on the plane of focus (V.focus[q] along the axis).
    Returns (origin, unit direction)."""
    r = V.lens[q] * math.sqrt(u0)
    phi = 2.0 * math.pi * u1
    ia = 1.0 / math.sqrt(V.a[q, 0] ** 2 + V.a[q, 1] ** 2 + V.a[q, 2] ** 2)
    ib = 1.0 / math.sqrt(V.b[q, 0] ** 2 + V.b[q, 1] ** 2 + V.b[q, 2] ** 2)
    ca, sb = r * math.cos(phi) * ia, r * math.sin(phi) * ib
    ox = V.o[q, 0] + ca * V.a[q, 0] + sb * V.b[q, 0]
    oy = V.o[q, 1] + ca * V.a[q, 1] + sb * V.b[q, 1]
    oz = V.o[q, 2] + ca * V.a[q, 2] + sb * V.b[q, 2]
    t = V.focus[q] / (dx * V.axis[q, 0] + dy * V.axis[q, 1] + dz * V.axis[q, 2])
    fx, fy, fz = V.o[q, 0] + t * dx - ox, V.o[q, 1] + t * dy - oy, V.o[q, 2] + t * dz - oz
    inv = 1.0 / math.sqrt(fx * fx + fy * fy + fz * fz)
    return ox, oy, oz, fx * inv, fy * inv, fz * inv


@njit(cache=True, error_model="numpy", _nrt=False)
def light_along(L, j, ox, oy, oz, ax, ay, az):
    """Light j as a view at o with axis a sees it directly: (E⊥ at o, lx; the offset to it (3); the shadow ray's
    t_max; its distance; the cosine of its angle from the axis). E⊥ is 0 where the view sees none of it: an area
    light (the paths themselves find it), a light that gives o nothing, or one behind the view."""
    if light_flags(L, j) & AREA_EMITTER:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0
    e, sx, sy, sz, t_max = light_connect(L, j, ox, oy, oz, ax, ay, az, 0.5, 0.5, 0.5)
    if e <= 0.0:
        return 0.0, sx, sy, sz, t_max, 1.0, 0.0
    dist = math.sqrt(sx * sx + sy * sy + sz * sz)
    cos_a = (sx * ax + sy * ay + sz * az) / dist
    return (e if cos_a > 0.0 else 0.0), sx, sy, sz, t_max, dist, cos_a


@njit(cache=True, error_model="numpy", _nrt=False)
def in_pixel(V, q, fx, fy, fz):
    """Whether the film point at offset f from pixel q's corner lies in the pixel: its coordinates along the
    pixel's edges a and b in [0, 1)."""
    a2 = V.a[q, 0] ** 2 + V.a[q, 1] ** 2 + V.a[q, 2] ** 2
    b2 = V.b[q, 0] ** 2 + V.b[q, 1] ** 2 + V.b[q, 2] ** 2
    s = (fx * V.a[q, 0] + fy * V.a[q, 1] + fz * V.a[q, 2]) / a2
    t = (fx * V.b[q, 0] + fy * V.b[q, 1] + fz * V.b[q, 2]) / b2
    return 0.0 <= s < 1.0 and 0.0 <= t < 1.0


@njit(cache=True, error_model="numpy", _nrt=False)
def lens_point_lights(sa, L, V, q, ox, oy, oz, stack, tstack):
    """The point-like lights one lens point (ox, oy, oz) of pixel q sees: for each light, the film point its light
    reaches through that lens point (through the light's image on the plane of focus); where that falls in the pixel,
    E⊥ / (cos³θ' × film area), θ' the ray's angle from the axis (the lens-point form of `seen_point_lights`). Its mean
    over the lens points of a pixel's paths is the pixel's mean luminance of the lights, unbiased."""
    total = 0.0
    for j in range(L.kind.shape[0]):
        e, sx, sy, sz, t_max, dist, cos_a = light_along(L, j, ox, oy, oz, V.axis[q, 0], V.axis[q, 1], V.axis[q, 2])
        if e <= 0.0:
            continue
        k = V.focus[q] / (cos_a * dist)   # the ray from the lens point reaches the plane of focus here
        px = ox + k * sx - V.o[q, 0]
        py = oy + k * sy - V.o[q, 1]
        pz = oz + k * sz - V.o[q, 2]
        f = 1.0 / V.focus[q]              # … which the pinhole ray through this film point meets
        if not in_pixel(V, q, px * f - V.c[q, 0], py * f - V.c[q, 1], pz * f - V.c[q, 2]):
            continue
        if any_with_stacks(sa, ox, oy, oz, sx, sy, sz, t_max, stack, tstack):
            continue
        total += e / cos_a / (cos_a ** 3 * V.size[q])
    return total


@njit(cache=True, error_model="numpy", _nrt=False)
def power_heuristic(p, other):
    """Veach's power heuristic (β = 2): the weight of a strategy of density p against one of density `other`."""
    return p * p / (p * p + other * other)


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def light_sample(sa, L, x, y, z, nx, ny, nz, pb_scale, u0, u1, u2, u3, stack, tstack):
    """Next-event estimation at x (off its surface, unit normal n): the illuminance (lx) from one light picked in
    proportion to its flux, divided by the pick's probability, MIS-weighted against a diffuse lobe that draws the
    same direction with density pb_scale × cosθ (an area light's; a point-like light's weight is 1)."""
    j, pj = pick_light(L, u0)
    if pj <= 0.0:
        return 0.0
    e, sx, sy, sz, t_max = light_connect(L, j, x, y, z, nx, ny, nz, u1, u2, u3)
    if e <= 0.0:
        return 0.0
    if any_with_stacks(sa, x, y, z, sx, sy, sz, t_max, stack, tstack):
        return 0.0
    est = e / pj
    if light_flags(L, j) & AREA_EMITTER and pb_scale > 0.0:
        cos_x = (sx * nx + sy * ny + sz * nz) / math.sqrt(sx * sx + sy * sy + sz * sz)
        # the light's density in solid angle, pj d²/(cosθ_l A) = pj M cosθ_x/(π e) (e = M/π cosθ_l cosθ_x A/d²)
        pl = pj * L.par[j, P_I0] * cos_x / (math.pi * e)
        est *= power_heuristic(pl, pb_scale * cos_x)
    return est


@njit(cache=True, error_model="numpy", _nrt=False)
def seen_point_lights(sa, L, V, q, stack, tstack):
    """The luminance (cd/m²) view q sees of the point-like lights in its field, exactly: E⊥/Ω for a cone that holds
    a light, E⊥/(cos³θ × film area) for the pixel a light falls in (module docstring); 0 where it is occluded."""
    ox, oy, oz = V.o[q, 0], V.o[q, 1], V.o[q, 2]
    total = 0.0
    if V.lens[q] > 0.0:
        return 0.0     # a thin lens: each path adds them from its own lens point (`lens_point_lights`)
    for j in range(L.kind.shape[0]):
        e, sx, sy, sz, t_max, dist, cos_a = light_along(L, j, ox, oy, oz, V.axis[q, 0], V.axis[q, 1], V.axis[q, 2])
        if e <= 0.0:
            continue
        if V.kind[q] == CONE:
            if cos_a < V.cos_max[q]:
                continue
            val = e / cos_a / V.size[q]
        else:
            on_film = 1.0 / (dist * cos_a)   # the light's direction scaled onto the film (unit distance along axis)
            if not in_pixel(V, q, sx * on_film - V.c[q, 0], sy * on_film - V.c[q, 1], sz * on_film - V.c[q, 2]):
                continue
            val = e / cos_a / (cos_a ** 3 * V.size[q])
        if any_with_stacks(sa, ox, oy, oz, sx, sy, sz, t_max, stack, tstack):
            continue
        total += val
    return total


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def trace_view(sa, M, L, V, E, P, q, key, counters, med, pol, chain, stack, tstack):
    """One path from the eye of view q: (an unbiased estimate of the luminance the paths find, cd/m²; 1.0 where
    the view ray met a specular surface (or took a specular lobe) before any diffuse one, else 0.0). A traced area
    light met after a specular vertex by a path whose first vertex was diffuse, or whose first diffuse vertex came
    after flat faces only that light tracing joins it back through (`through_flat.same_join`), adds nothing: light
    tracing (`P`) has that path (module docstring); such a path does not count as seeing through a specular chain."""
    dx, dy, dz = view_direction(V, q, uniform(key, 0), uniform(key, 1))
    x, y, z = V.o[q, 0], V.o[q, 1], V.o[q, 2]
    dim = 2
    lum = 0.0
    if V.lens[q] > 0.0:   # a thin lens: from a point on the lens through the point in focus
        x, y, z, dx, dy, dz = lens_ray(V, q, dx, dy, dz, uniform(key, 2), uniform(key, 3))
        dim = 4
        lum += lens_point_lights(sa, L, V, q, x, y, z, stack, tstack)
    x0, y0, z0 = x, y, z      # the eye point (on the lens)
    n_flat = 0                # flat faces (`through_flat`) the view ray crossed before anything else, the first at
    x1, y1, z1 = x, y, z      # (x1, y1, z1)
    w = 1.0
    pb_scale = 0.0    # > 0: d was drawn from a diffuse lobe with density pb_scale × cos_prev (MIS on emission)
    cos_prev = 0.0
    depth = 0
    diffuse_bounces = 0
    from_eye = True   # no diffuse vertex yet: a specular chain from here is one the eye looks along
    eye_diffuse = False   # the first vertex scattered diffusely: light tracing may join there
    through_specular = 0.0
    caustic = False
    truncated = True
    for bounce in range(MAX_BOUNCES):
        t, inst, prim, hu, hv, ngx, ngy, ngz = closest_with_stacks(sa, x, y, z, dx, dy, dz, math.inf, stack, tstack)
        counters[C_VIEW_RAYS] += 1
        if inst < 0:
            truncated = False
            break
        px, py, pz = x + t * dx, y + t * dy, z + t * dz
        cos_hit = -(dx * ngx + dy * ngy + dz * ngz)
        lit = inst < E.le.shape[0] and E.le[inst] > 0.0 and cos_hit > 0.0 and emits(E, inst, prim)
        if lit and eye_diffuse and pb_scale == 0.0 and traced_area(P, E, inst):
            counters[C_LEFT] += 1
            lit = P.photons[0] <= 0   # after a specular vertex, seen from a diffuse first vertex: light tracing's
        if lit:
            mis = 1.0
            if pb_scale > 0.0:
                j = E.light[inst]
                pj = L.cdf[j] - (L.cdf[j - 1] if j > 0 else 0.0)
                mis = power_heuristic(pb_scale * cos_prev, pj * t * t / (cos_hit * L.a_area[j]))
            lum += w * E.le[inst] * mis
        fx, fy, fz = arrival_normal(ngx, ngy, ngz, dx, dy, dz)
        sx, sy, sz = offset_ray_origin(px, py, pz, ngx, ngy, ngz, fx, fy, fz)
        rho = surface_albedo(sa, M, inst, prim)
        flags = surface_flags(sa, M, inst, prim)   # an element's feature may have a surface of its own
        lambertian = flags == DIFFUSE   # only a Lambertian lobe: sampled here, by its cosine
        if rho > 0.0:
            lobe = 1.0 / math.pi if lambertian else rho / math.pi   # the diffuse lobe's density / cosθ
            lum += w * rho / math.pi * light_sample(sa, L, sx, sy, sz, fx, fy, fz, lobe, uniform(key, dim),
                                                    uniform(key, dim + 1), uniform(key, dim + 2),
                                                    uniform(key, dim + 3), stack, tstack)
            counters[C_VIEW_RAYS] += 1
            dim += 4
        joined_back = n_flat > 0 and bounce == n_flat and rho > 0.0 and same_join(
            sa, M, sx, sy, sz, fx, fy, fz, x0, y0, z0, n_flat, x1, y1, z1, med, depth, chain, stack, tstack, P.join_at)
        if joined_back:   # light tracing joins this vertex through the faces: its light is not missing
            through_specular = 0.0
        if lambertian:
            w *= rho
            if w <= 0.0:
                truncated = False
                break
            dx, dy, dz = sample_cosine(fx, fy, fz, uniform(key, dim), uniform(key, dim + 1))
            dim += 2
            pb_scale, cos_prev = 1.0 / math.pi, dx * fx + dy * fy + dz * fz
            x, y, z = sx, sy, sz
            eye_diffuse = eye_diffuse or bounce == 0 or joined_back
            from_eye = False
            diffuse_bounces += 1
            if diffuse_bounces >= RR_DEPTH:
                survive = min(1.0, w)
                if uniform(key, dim) >= survive:
                    truncated = False
                    break
                dim += 1
                w /= survive
            continue
        # a specular surface (met, whether it reflects or absorbs)
        if rho == 0.0 and flags != 0:
            if from_eye:
                through_specular = 1.0
            else:
                caustic = True
        status, ox, oy, oz, f, depth, dim = scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth,
                                                    key, dim, 0.0, pol)
        if status == STACK_FULL:
            counters[C_STACK] += 1
        if status != CONTINUES:
            truncated = False
            break
        if P.flat[0] != 0 and n_flat == bounce and ox * fx + oy * fy + oz * fz < 0.0 and \
                flat_face(sa, M, inst, prim, hu, hv, ngx, ngy, ngz):   # through a flat face, as from the eye so far
            n_flat += 1
            if bounce == 0:
                x1, y1, z1 = px, py, pz
        w *= f
        # which lobe drew the new direction: a diffuse one (MIS applies) unless it is the mirror direction
        diffuse_lobe = False
        if rho > 0.0 and ox * fx + oy * fy + oz * fz > 0.0:
            mx, my, mz = reflect_specular(sa, inst, prim, hu, hv, dx, dy, dz, fx, fy, fz)
            diffuse_lobe = not (mx == ox and my == oy and mz == oz)
        if diffuse_lobe:
            pb_scale, cos_prev = rho / math.pi, ox * fx + oy * fy + oz * fz
            eye_diffuse = eye_diffuse or bounce == 0 or joined_back
            from_eye = False
        else:
            pb_scale = 0.0
            if rho > 0.0:   # the specular lobe of a surface that also has a diffuse one
                if from_eye:
                    through_specular = 1.0
                else:
                    caustic = True
        dx, dy, dz = ox, oy, oz
        x, y, z = offset_ray_origin(px, py, pz, ngx, ngy, ngz, dx, dy, dz)
    if truncated:
        counters[C_TRUNCATED] += 1
    if caustic:
        counters[C_CAUSTIC] += 1
    if not math.isfinite(lum):
        counters[C_REJECTED] += 1
        return 0.0, through_specular
    return lum, through_specular


@njit(cache=True, error_model="numpy", _nrt=False)
def radiance_batch(sa, M, L, V, E, P, seed, batch, paths, lum, share, counters, med, pol, chain, stack, tstack):
    """Batch `batch`: `paths` paths per view and `P.photons` light paths (`trace_light`); each view's luminance
    estimate (cd/m²) into lum (k,), its share of paths through a specular chain from the eye into share (k,), the
    counters into counters (`COUNTERS`). With no paths (a pilot's light tracing alone) lum holds light tracing's
    part only."""
    for q in range(V.kind.shape[0] if paths > 0 else 0):
        acc = 0.0
        spec = 0.0
        for i in range(paths):
            key = path_key(seed, batch, q * paths + i)
            v, s = trace_view(sa, M, L, V, E, P, q, key, counters, med, pol, chain, stack, tstack)
            acc += v
            spec += s
        lum[q] = acc / paths + seen_point_lights(sa, L, V, q, stack, tstack)
        share[q] = spec / paths
    if P.photons[0] > 0:
        trace_light(sa, M, L, V, P, seed, batch, V.kind.shape[0] * paths, lum, counters, med, pol, chain, stack,
                    tstack)


@njit(cache=True, error_model="numpy", nogil=True)
def radiance_batches(sa, M, L, V, E, P, seed, batch0, n_batches, paths):
    """Batches batch0 … batch0+n_batches−1, `paths` paths per view and `P.photons` light paths each.

    Returns (values (n_batches, 2k): each batch's luminance (cd/m²) per view, then its share of paths through a
    specular chain from the eye per view; counters (n_batches, 9) int64, `COUNTERS`). Serial and without the GIL,
    like `tracer.transport.backward.backward_batches`.
    """
    k = V.kind.shape[0]
    out = np.zeros((n_batches, 2 * k))
    cnt = np.zeros((n_batches, len(COUNTERS)), np.int64)
    med = np.empty(MEDIUM_DEPTH, np.int64)
    pol = np.zeros(N_POL)
    chain = np.empty(CHAIN_SHAPE)
    for b in range(n_batches):
        stack, tstack = new_stacks()
        row = out[b]
        radiance_batch(sa, M, L, V, E, P, seed, batch0 + b, paths, row[:k], row[k:], cnt[b], med, pol, chain, stack,
                       tstack)
    return out, cnt
