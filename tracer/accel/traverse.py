"""Two-level traversal: the top level over instance boxes, each instance's bottom level in object space.

All functions are ``@njit(cache=True, error_model="numpy")`` and take a :class:`SceneArrays` (``scene.arrays()`` after
``scene.commit()``), so light transport can call them from its own jitted code (docs/CONTRACTS.md).
Those meant for a loop over rays (``*_with_stack(s)``) allocate nothing and are compiled without numba's
reference counting (``_nrt=False``): with it, every call counted references to each of the scene's two
dozen arrays, which took as long as the traversal itself (measured: 1.7x the time per camera ray).

Conventions
-----------
* Rays are ``o + t d`` in world space, ``d`` need not be unit: ``t`` is in units of ``|d|``
  (world metres for a unit ``d``). The ray is mapped into object space with ``object_from_world``
  *without* renormalising ``d``, so the parametric ``t`` is the same in both spaces.
* ``inst_id`` is the public instance id of :class:`tracer.Scene` (ids index the instance arrays
  directly; removed ids have ``inst_kind == -1`` and are in no top level). ``prim_id`` is the
  triangle's index in the ``triangles`` array given to ``add_geometry``.
* Normals come back in world space: object normals times the inverse transpose of
  ``world_from_object`` (the transpose of ``object_from_world``'s linear part), so a mirrored
  instance keeps its outward side outward.
* Sensor instances live in their own top level (``sen_*``): closest-hit and any-hit never see them.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from tracer.accel import rows8, wide
from tracer.accel.blas import STACK_SIZE
from tracer.accel.rows4 import up32
from tracer.accel.wide import MISS, pop_nearer, prefetch, ray_inverse, slab
from tracer.jit import njit
from tracer.kinds import dispatch, mesh

#: where the top level's entries start in the traversal stacks (:func:`new_stacks`; a bottom level's from
#: :data:`tracer.accel.wide.STACK_BASE`), and where :func:`tracer.accel.rows8.slab8` leaves its distances
TOP8_BASE = 0
TOP8_DIST = wide.STACK_BASE + 2 * STACK_SIZE
#: the stacks' length (:func:`new_stacks`; each lane of :mod:`tracer.accel.lanes` has this much of its own)
STACK_LEN = TOP8_DIST + rows8.WIDTH


class SceneArrays(NamedTuple):
    """Everything a query needs, as arrays (structure of arrays, packed at commit).

    Geometry store (append-only; indices local to a geometry, offsets below):
    ``bvh_f`` (16 R,) f4 and ``bvh_i`` (16 R,) i4, two flat views of the same 64-byte-aligned 4-wide
    quantised BLAS rows (:func:`tracer.accel.rows4.pack_wide`, 16 values per row); ``tri_v`` (9 M,) f4 —
    triangle vertices in leaf order, 9 values each (exact: the geometry's vertices are float32; all arithmetic
    on them is float64); ``tri_prim`` (M,) i4 — original triangle index of each row; ``prim_slot`` (M,) i4 —
    the inverse (original index -> local row);
    ``tri_n`` (M, 9) f4 — vertex normals in leaf order (zero where the mesh has none);
    ``geom_node0``, ``geom_tri0`` (G,) i8, ``geom_ntri`` (G,) i8, ``geom_has_normals`` (G,) bool.

    Instances (indexed by instance id): ``inst_kind`` (I,) i4 (-1: removed), ``inst_geom`` (I,) i4,
    ``world_from_object`` and ``object_from_world`` (I, 3, 4) f8 (affine rows).

    Top levels over instance ids: solids ``top_f, top_i, top_items`` in 8-wide float32 rows
    (:mod:`tracer.accel.rows8`), sensors ``sen_f, sen_i, sen_items`` in binary child-box rows
    (:func:`tracer.accel.rows4.pack_rows`); leaves index ``*_items``. ``top_rec`` (4 n,) i8: the solid items'
    :func:`tracer.accel.tlas.instance_records` (what entering each one needs, in leaf order).

    Elements with an inside (:mod:`tracer.kinds.relief`, packed by :mod:`tracer.elements.support`): ``inst_aux`` (I,) i4
    — an instance's first row in them (-1: none; a part's rows are consecutive); per row ``el_f`` (R, NF) f8 and
    ``el_i`` (R, NI) i8 (the columns of :mod:`tracer.elements.features`); shared tables ``el_prim`` i4 (triangle maps),
    ``el_bits`` u1 (kept lattice sites), ``el_uv`` (P, 2) f4 (listed feature centres, mm), ``el_bin`` i4 and ``el_item``
    i4 (their cells), ``el_tab`` (T, B) f8 (the rows of the tabulated BSDFs of elements used through their ``bsdf``
    model: :mod:`tracer.elements.bsdf`), ``el_face`` (Q, 4) f8 (the face planes of mesh features:
    :mod:`tracer.elements.shapes.mesh`).
    """

    bvh_f: np.ndarray
    bvh_i: np.ndarray
    tri_v: np.ndarray
    tri_prim: np.ndarray
    prim_slot: np.ndarray
    tri_n: np.ndarray
    geom_node0: np.ndarray
    geom_tri0: np.ndarray
    geom_ntri: np.ndarray
    geom_has_normals: np.ndarray
    inst_kind: np.ndarray
    inst_geom: np.ndarray
    world_from_object: np.ndarray
    object_from_world: np.ndarray
    top_f: np.ndarray
    top_i: np.ndarray
    top_items: np.ndarray
    top_rec: np.ndarray
    sen_f: np.ndarray
    sen_i: np.ndarray
    sen_items: np.ndarray
    inst_aux: np.ndarray
    el_f: np.ndarray
    el_i: np.ndarray
    el_prim: np.ndarray
    el_bits: np.ndarray
    el_uv: np.ndarray
    el_bin: np.ndarray
    el_item: np.ndarray
    el_tab: np.ndarray
    el_face: np.ndarray


#: dtype and dimensions of each :class:`SceneArrays` field, as :class:`tracer.Scene` packs them
#: (tests/tracer/test_warmup.py compares them with a committed scene's)
SCENE_ARRAY_TYPES = {"bvh_f": ("f4", 1), "bvh_i": ("i4", 1), "tri_v": ("f4", 1), "tri_prim": ("i4", 1),
                     "prim_slot": ("i4", 1), "tri_n": ("f4", 2), "geom_node0": ("i8", 1), "geom_tri0": ("i8", 1),
                     "geom_ntri": ("i8", 1), "geom_has_normals": ("?", 1), "inst_kind": ("i4", 1),
                     "inst_geom": ("i4", 1), "world_from_object": ("f8", 3), "object_from_world": ("f8", 3),
                     "top_f": ("f4", 1), "top_i": ("i4", 1), "top_items": ("i4", 1), "top_rec": ("i8", 1),
                     "sen_f": ("f4", 1), "sen_i": ("i4", 1), "sen_items": ("i4", 1), "inst_aux": ("i4", 1),
                     "el_f": ("f8", 2), "el_i": ("i8", 2), "el_prim": ("i4", 1), "el_bits": ("u1", 1),
                     "el_uv": ("f4", 2), "el_bin": ("i4", 1), "el_item": ("i4", 1),
                     "el_tab": ("f8", 2), "el_face": ("f8", 2)}


def empty_scene_arrays() -> SceneArrays:
    """A :class:`SceneArrays` of empty arrays of the right types: what compiling a kernel by its signature needs
    (`tracer.warmup`), without committing a scene (which compiles the builders)."""
    return SceneArrays(**{name: np.empty((0,) * ndim, dtype) for name, (dtype, ndim) in SCENE_ARRAY_TYPES.items()})


@njit(cache=True, error_model="numpy", inline="always")
def to_object(m, inst, ox, oy, oz, dx, dy, dz):
    rox = m[inst, 0, 0] * ox + m[inst, 0, 1] * oy + m[inst, 0, 2] * oz + m[inst, 0, 3]
    roy = m[inst, 1, 0] * ox + m[inst, 1, 1] * oy + m[inst, 1, 2] * oz + m[inst, 1, 3]
    roz = m[inst, 2, 0] * ox + m[inst, 2, 1] * oy + m[inst, 2, 2] * oz + m[inst, 2, 3]
    rdx = m[inst, 0, 0] * dx + m[inst, 0, 1] * dy + m[inst, 0, 2] * dz
    rdy = m[inst, 1, 0] * dx + m[inst, 1, 1] * dy + m[inst, 1, 2] * dz
    rdz = m[inst, 2, 0] * dx + m[inst, 2, 1] * dy + m[inst, 2, 2] * dz
    return rox, roy, roz, rdx, rdy, rdz


@njit(cache=True, error_model="numpy", inline="always")
def normal_to_world(sa, inst, nx, ny, nz):
    """Object-space normal -> unit world-space normal (inverse transpose of world_from_object)."""
    m = sa.object_from_world
    wx = m[inst, 0, 0] * nx + m[inst, 1, 0] * ny + m[inst, 2, 0] * nz
    wy = m[inst, 0, 1] * nx + m[inst, 1, 1] * ny + m[inst, 2, 1] * nz
    wz = m[inst, 0, 2] * nx + m[inst, 1, 2] * ny + m[inst, 2, 2] * nz
    ln = math.sqrt(wx * wx + wy * wy + wz * wz)
    if ln > 0.0 and ln < np.inf:
        return wx / ln, wy / ln, wz / ln
    return 0.0, 0.0, 0.0


@njit(cache=True, error_model="numpy", _nrt=False)
def point_to_world(sa, inst, px, py, pz):
    """Object-space point -> world space."""
    m = sa.world_from_object
    return (m[inst, 0, 0] * px + m[inst, 0, 1] * py + m[inst, 0, 2] * pz + m[inst, 0, 3],
            m[inst, 1, 0] * px + m[inst, 1, 1] * py + m[inst, 1, 2] * pz + m[inst, 1, 3],
            m[inst, 2, 0] * px + m[inst, 2, 1] * py + m[inst, 2, 2] * pz + m[inst, 2, 3])


@njit(cache=True, error_model="numpy", inline="always")
def walk_scene(sa, ox, oy, oz, dx, dy, dz, t_max, any_hit, stack, tstack, inline_mesh):
    """Top-level traversal over the 8-wide rows ``sa.top_f`` (:mod:`tracer.accel.rows8`; leaves hold instance
    ids): each instance hit is entered in object space, a mesh straight from its record (``sa.top_rec``),
    any other kind through :mod:`tracer.kinds.dispatch`.

    ``inline_mesh`` (a constant at each call site): walk a mesh's rows inlined (:func:`tracer.accel.wide.walk_rows`,
    6 % fewer instructions per camera ray in the paper's scene 3) rather than through a call. Only the batch
    kernel's walk does (:func:`tracer.accel.lanes._serial_block`): each inlined copy adds compile time, and
    :func:`closest_with_stacks` and :func:`any_with_stacks` are compiled apart and called per transport variant.
    """
    best_t = t_max
    best_inst = -1
    best_slot = -1
    bu = 0.0
    bv = 0.0
    if sa.top_f.shape[0] == 0:
        return best_t, best_inst, best_slot, bu, bv
    items = sa.top_items
    rec = sa.top_rec
    m = sa.object_from_world
    if items.shape[0] == 1:   # one instance: its bottom level's first row tests what its box would
        inst = items[0]
        rox, roy, roz, rdx, rdy, rdz = to_object(m, inst, ox, oy, oz, dx, dy, dz)
        hit, t, slot, u, v = dispatch.intersect_solid(sa, inst, rox, roy, roz, rdx, rdy, rdz, best_t, any_hit, stack,
                                                      tstack)
        if hit:
            return t, inst, slot, u, v
        return best_t, best_inst, best_slot, bu, bv
    onx, ony, onz, ofx, ofy, ofz, ix, iy, iz, ixe, iye, ize, xl, yl, zl = rows8.ray8(ox, oy, oz, dx, dy, dz)
    bf = sa.top_f
    bi = sa.top_i
    t32 = np.float64(up32(best_t))
    sp = TOP8_BASE
    ref = 0
    while True:
        if ref >= 0:
            r = rows8.ROW * ref
            hits = rows8.slab8(bf, r, onx, ony, onz, ofx, ofy, ofz, ix, iy, iz, ixe, iye, ize, xl, yl, zl, t32, tstack,
                         TOP8_DIST)
            if hits != 0:
                ref, sp = rows8.descend8(bi, r, hits, stack, tstack, TOP8_DIST, sp)
                if ref >= 0:
                    for line in range(0, rows8.ROW, 16):   # its four cache lines
                        prefetch(bf, rows8.ROW * ref + line)
                continue
        else:
            x = -ref - 1
            first = x >> 4
            for q in range(first, first + (x & 15)):
                inst = rec[4 * q]
                kind = rec[4 * q + 1]
                if kind < 0:
                    continue
                rox, roy, roz, rdx, rdy, rdz = to_object(m, inst, ox, oy, oz, dx, dy, dz)
                if kind == mesh.KIND and inline_mesh:   # straight from the record (tracer.accel.tlas.instance_records)
                    hit, t, slot, u, v = wide.walk_rows(sa.bvh_f, sa.bvh_i, sa.tri_v, rec[4 * q + 2], rec[4 * q + 3],
                                                        rox, roy, roz, rdx, rdy, rdz, best_t, any_hit, stack, tstack)
                elif kind == mesh.KIND:
                    hit, t, slot, u, v = wide.traverse_rows(sa.bvh_f, sa.bvh_i, sa.tri_v, rec[4 * q + 2],
                                                            rec[4 * q + 3], rox, roy, roz, rdx, rdy, rdz, best_t,
                                                            any_hit, stack, tstack)
                else:
                    hit, t, slot, u, v = dispatch.intersect_solid(sa, inst, rox, roy, roz, rdx, rdy, rdz,
                                                                  best_t, any_hit, stack, tstack)
                if hit:
                    best_t = t
                    t32 = np.float64(up32(best_t))
                    best_inst = inst
                    best_slot = slot
                    bu = u
                    bv = v
                    if any_hit:
                        return best_t, best_inst, best_slot, bu, bv
        ref, sp = pop_nearer(stack, tstack, sp, TOP8_BASE, best_t)
        if ref == MISS:
            break
    return best_t, best_inst, best_slot, bu, bv


@njit(cache=True, error_model="numpy")
def new_stacks():
    """Traversal stacks for the ``*_with_stacks`` functions: ``(stack, tstack)``, of the same length.

    The top level uses the first :data:`tracer.accel.rows8.STACK` entries, a bottom level the next 2 STACK_SIZE
    (from :data:`tracer.accel.wide.STACK_BASE`: a 4-wide level pushes up to three entries per level, of about
    half the binary depth, which :func:`tracer.accel.blas.check_topology` keeps below STACK_SIZE), then 8 slots
    for :func:`tracer.accel.rows8.slab8`'s distances (:data:`TOP8_DIST`)."""
    return np.empty(STACK_LEN, np.int64), np.empty(STACK_LEN)


@njit(cache=True, error_model="numpy", _nrt=False)
def closest_with_stacks(sa, ox, oy, oz, dx, dy, dz, t_max, stack, tstack):
    """:func:`intersect_closest` with caller-provided traversal stacks (:func:`new_stacks`): the form for
    jitted loops over many rays (light transport). A real function, compiled once: inlined, the whole
    two-level traversal was compiled again into every transport variant (twice the cold compile)."""
    t, inst, slot, u, v = walk_scene(sa, ox, oy, oz, dx, dy, dz, t_max, False, stack, tstack, False)
    return public_hit(sa, t, inst, slot, u, v)


@njit(cache=True, error_model="numpy", inline="always")
def public_hit(sa, t, inst, slot, u, v):
    """A traversal's raw result (the kind's ``slot``) -> ``(t, inst_id, prim_id, u, v, ngx, ngy, ngz)``
    as :func:`intersect_closest` returns it (``inf``, -1 and zeros on a miss)."""
    if inst < 0:
        return np.inf, -1, -1, 0.0, 0.0, 0.0, 0.0, 0.0
    prim = dispatch.primitive_solid(sa, inst, slot)
    nx, ny, nz = dispatch.normal_solid(sa, inst, slot, u, v)
    wx, wy, wz = normal_to_world(sa, inst, nx, ny, nz)
    return t, inst, prim, u, v, wx, wy, wz


@njit(cache=True, error_model="numpy")
def intersect_closest(sa, ox, oy, oz, dx, dy, dz, t_max):
    """Closest hit of the ray ``o + t d``, ``0 < t < t_max``, with the solid (non-sensor) instances.

    Returns
    -------
    (t, inst_id, prim_id, u, v, ngx, ngy, ngz)
        ``t = inf``, ``inst_id = prim_id = -1`` on a miss; ``(u, v)`` barycentrics
        (``p = (1-u-v) v0 + u v1 + v v2``); ``ng`` the unit world-space geometric normal of the
        object-space ``(v1-v0) x (v2-v0)`` (zeros on a miss).
    """
    stack, tstack = new_stacks()
    return closest_with_stacks(sa, ox, oy, oz, dx, dy, dz, t_max, stack, tstack)


@njit(cache=True, error_model="numpy", _nrt=False)
def any_with_stacks(sa, ox, oy, oz, dx, dy, dz, t_max, stack, tstack):
    """:func:`intersect_any` with caller-provided traversal stacks (:func:`new_stacks`)."""
    t, inst, slot, u, v = walk_scene(sa, ox, oy, oz, dx, dy, dz, t_max, True, stack, tstack, False)
    return inst >= 0


@njit(cache=True, error_model="numpy")
def closest_each(sa, o, d, t_max, out_t, out_inst, out_normal):
    """Closest hits of a few rays ``o[i] + t d[i]`` ((k, 3) arrays, t_max (k,)) one after the other, with
    the one walk transport compiles anyway (:func:`closest_with_stacks`): for a query's own probes, which
    need no batch kernel (`Scene.intersect` would compile one, at half a minute, for a handful of rays).
    Fills out_t (k,) (inf on a miss), out_inst (k,) (-1 on a miss), out_normal (k, 3) unit geometric normal."""
    stack, tstack = new_stacks()
    for i in range(o.shape[0]):
        t, inst, prim, u, v, nx, ny, nz = closest_with_stacks(sa, o[i, 0], o[i, 1], o[i, 2], d[i, 0], d[i, 1],
                                                              d[i, 2], t_max[i], stack, tstack)
        out_t[i], out_inst[i] = t, inst
        out_normal[i, 0], out_normal[i, 1], out_normal[i, 2] = nx, ny, nz


@njit(cache=True, error_model="numpy")
def intersect_any(sa, ox, oy, oz, dx, dy, dz, t_max):
    """True when any solid instance is hit with ``0 < t < t_max`` (shadow rays; sensors ignored)."""
    stack, tstack = new_stacks()
    return any_with_stacks(sa, ox, oy, oz, dx, dy, dz, t_max, stack, tstack)


@njit(cache=True, error_model="numpy")
def sensor_crossings(sa, ox, oy, oz, dx, dy, dz, t_max, out_inst, out_t, out_u, out_v, out_cos):
    """Every sensor instance the segment ``0 < t < t_max`` crosses: :func:`sensor_crossings_with_stack`
    with a stack of its own."""
    return sensor_crossings_with_stack(sa, ox, oy, oz, dx, dy, dz, t_max, out_inst, out_t, out_u, out_v, out_cos,
                                       np.empty(STACK_SIZE, np.int64))


@njit(cache=True, error_model="numpy", _nrt=False)
def sensor_crossings_with_stack(sa, ox, oy, oz, dx, dy, dz, t_max, out_inst, out_t, out_u, out_v, out_cos, stack):
    """Every sensor instance the segment ``0 < t < t_max`` crosses, sorted by ``t``.

    Parameters
    ----------
    out_inst : (c,) int array, out_t, out_u, out_v, out_cos : (c,) float arrays
        Filled with the first ``count`` crossings; at most ``c`` are kept (the nearest ones).

    Returns
    -------
    count : int
        ``(u, v)``: sensor object-space coordinates (disk: unit disk; rect: ``[0, 1]^2``);
        ``cos = -dot(d, n_world) / |d|`` (> 0: the ray arrives on the sensor's front side).

    ``stack``: (at least :data:`tracer.accel.blas.STACK_SIZE`,) int64 scratch (a traversal stack of
    :func:`new_stacks` will do).
    """
    cap = out_inst.shape[0]
    count = 0
    if sa.sen_f.shape[0] == 0 or cap == 0:
        return 0
    ix, iy, iz, ixe, iye, ize, xl, yl, zl = ray_inverse(dx, dy, dz)
    dlen = math.sqrt(dx * dx + dy * dy + dz * dz)
    bf = sa.sen_f
    bi = sa.sen_i
    m = sa.object_from_world
    sp = 1
    stack[0] = 0
    while sp > 0:
        sp -= 1
        ref = stack[sp]
        if ref >= 0:
            r = 16 * ref
            hl, _ = slab(bf, r, ox, oy, oz, ix, iy, iz, ixe, iye, ize, xl, yl, zl, t_max)
            hr, _ = slab(bf, r + 6, ox, oy, oz, ix, iy, iz, ixe, iye, ize, xl, yl, zl, t_max)
            if hl:
                stack[sp] = bi[r + 12]
                sp += 1
            if hr:
                stack[sp] = bi[r + 13]
                sp += 1
            continue
        x = -ref - 1
        first = x >> 4
        for q in range(first, first + (x & 15)):
            inst = sa.sen_items[q]
            rox, roy, roz, rdx, rdy, rdz = to_object(m, inst, ox, oy, oz, dx, dy, dz)
            hit, t, u, v = dispatch.cross_sensor(sa, inst, rox, roy, roz, rdx, rdy, rdz, t_max)
            if not hit:
                continue
            nx, ny, nz = normal_to_world(sa, inst, 0.0, 0.0, 1.0)
            cs = -(dx * nx + dy * ny + dz * nz) / dlen
            # insertion into the sorted list, dropping the farthest when full
            if count == cap:
                if t >= out_t[cap - 1]:
                    continue
                pos = cap - 1
            else:
                pos = count
                count += 1
            while pos > 0 and out_t[pos - 1] > t:
                out_inst[pos] = out_inst[pos - 1]
                out_t[pos] = out_t[pos - 1]
                out_u[pos] = out_u[pos - 1]
                out_v[pos] = out_v[pos - 1]
                out_cos[pos] = out_cos[pos - 1]
                pos -= 1
            out_inst[pos] = inst
            out_t[pos] = t
            out_u[pos] = u
            out_v[pos] = v
            out_cos[pos] = cs
    return count


@njit(cache=True, error_model="numpy", inline="always")
def shading_normal(sa, inst_id, prim_id, u, v):
    """Unit world-space shading normal: the interpolated vertex normal, the geometric one where the
    mesh has no normals (or they cancel)."""
    nx, ny, nz, _ = dispatch.shading_normal_object(sa, inst_id, prim_id, u, v)
    return normal_to_world(sa, inst_id, nx, ny, nz)


@njit(cache=True, error_model="numpy", inline="always")
def hit_point(sa, inst_id, prim_id, u, v):
    """World-space surface point from barycentrics: more accurate than ``o + t d`` for spawning, as
    its error depends on the vertex magnitudes only, not on how far the ray came."""
    px, py, pz = dispatch.point_object(sa, inst_id, prim_id, u, v)
    return point_to_world(sa, inst_id, px, py, pz)
