"""Kind 3: a part whose planar supports carry elements with an inside (:mod:`tracer.elements`).

The instance's geometry is the part without its supports; each support is a geometry of its own (``el_i[GEOM_S]`` of
its row; a part's rows are consecutive from ``inst_aux[inst]``, ``el_i[PART_N]`` of them), so a ray that misses every
feature meets the very triangles, with the very test, it meets without the elements. A ray is traced against the rest,
then each row's support, whose hit counts only outside that row's features' bases, and the features near its path
(found from the layout, :func:`tracer.elements.features.search`) up to the nearest hit so far.

Results: a triangle hit reports the ``slot`` of the rest or a support and the *part's* triangle index as its
primitive (so materials, surface tallies and shading normals read as without the elements); a feature hit reports
``slot = prim = -2 - (f * PART_ROWS + k)`` (``f`` the feature's index in the layout of the part's row ``k``) and
``(u, v)`` the hit's plane coordinates in mm, from which :func:`tracer.elements.features.surface` gives its point and
normal.
"""

from __future__ import annotations

from tracer.accel.wide import traverse_rows
from tracer.elements import features as fx
from tracer.jit import njit
from tracer.kinds import mesh

KIND = 3
SENSOR = False
GEOMETRY = None   # `tracer.Scene.instance_geometry` reports the part's own geometry id (kept by its row)


@njit(cache=True, error_model="numpy", inline="always")
def _to_frame(F, ox, oy, oz, dx, dy, dz):
    """The object-space ray in the element's frame, mm: ``(ou, ov, ow, du, dv, dw)`` (``t`` unchanged)."""
    s = F[fx.MM]
    px = ox - F[fx.O_X]
    py = oy - F[fx.O_X + 1]
    pz = oz - F[fx.O_X + 2]
    return (s * (px * F[fx.U_X] + py * F[fx.U_X + 1] + pz * F[fx.U_X + 2]),
            s * (px * F[fx.V_X] + py * F[fx.V_X + 1] + pz * F[fx.V_X + 2]),
            s * (px * F[fx.N_X] + py * F[fx.N_X + 1] + pz * F[fx.N_X + 2]),
            s * (dx * F[fx.U_X] + dy * F[fx.U_X + 1] + dz * F[fx.U_X + 2]),
            s * (dx * F[fx.V_X] + dy * F[fx.V_X + 1] + dz * F[fx.V_X + 2]),
            s * (dx * F[fx.N_X] + dy * F[fx.N_X + 1] + dz * F[fx.N_X + 2]))


@njit(cache=True, error_model="numpy", _nrt=False)
def intersect(sa, inst, ox, oy, oz, dx, dy, dz, t_max, any_hit, stack, tstack):
    """``(hit, t, slot, u, v)``: the nearest of the rest's hit, each support's outside its features' bases, and a
    feature's (the whole search also for ``any_hit``: a support hit inside a base is no hit)."""
    r0 = sa.inst_aux[inst]
    g = sa.inst_geom[inst]
    hit, t, slot, u, v = traverse_rows(sa.bvh_f, sa.bvh_i, sa.tri_v, sa.geom_node0[g], sa.geom_tri0[g], ox, oy, oz,
                                       dx, dy, dz, t_max, any_hit, stack, tstack) if sa.geom_ntri[g] > 0 else \
        (False, 0.0, -1, 0.0, 0.0)
    best = t if hit else t_max
    for k in range(sa.el_i[r0, fx.PART_N]):
        F = sa.el_f[r0 + k]
        I = sa.el_i[r0 + k]
        gs = I[fx.GEOM_S]
        hs, ts, ss, us, vs = traverse_rows(sa.bvh_f, sa.bvh_i, sa.tri_v, sa.geom_node0[gs], sa.geom_tri0[gs], ox, oy,
                                           oz, dx, dy, dz, best, False, stack, tstack)
        if I[fx.MODEL] != fx.EXACT:   # a table (bsdf, grating): the plain support, scattered by it (`dispatch`)
            if hs:
                hit, t, slot, u, v = True, ts, ss, us, vs
                best = ts
            continue
        ou, ov, ow, du, dv, dw = _to_frame(F, ox, oy, oz, dx, dy, dz)
        if hs and fx.feature_at(F, I, sa.el_bits, sa.el_uv, sa.el_bin, sa.el_item, sa.el_face, ou + ts * du,
                                ov + ts * dv) < 0:
            hit, t, slot, u, v = True, ts, ss, us, vs
            best = ts
        tf, f = fx.search(F, I, sa.el_bits, sa.el_uv, sa.el_bin, sa.el_item, sa.el_face, ou, ov, ow, du, dv, dw, 0.0,
                          best)
        if f >= 0:
            hit, t, slot, u, v = True, tf, -2 - (f * fx.PART_ROWS + k), ou + tf * du, ov + tf * dv
            best = tf
    return hit, t, slot, u, v


@njit(cache=True, error_model="numpy", inline="always")
def feature_row(sa, inst, prim):
    """``(row, feature)`` of a feature hit's primitive ``prim`` (< -1) on instance `inst`."""
    code = -2 - prim
    return sa.inst_aux[inst] + code % fx.PART_ROWS, code // fx.PART_ROWS


@njit(cache=True, error_model="numpy", inline="always")
def support_row(sa, inst, slot):
    """The row whose support holds triangle ``slot`` of the store; -1 for a triangle of the rest."""
    r0 = sa.inst_aux[inst]
    for k in range(sa.el_i[r0, fx.PART_N]):
        gs = sa.el_i[r0 + k, fx.GEOM_S]
        if sa.geom_tri0[gs] <= slot < sa.geom_tri0[gs] + sa.geom_ntri[gs]:
            return r0 + k
    return -1


@njit(cache=True, error_model="numpy", _nrt=False)
def primitive(sa, inst, slot):
    """The part's triangle index of a triangle hit; ``slot`` itself (``-2 - (f * PART_ROWS + k)``) for a feature's."""
    if slot < -1:
        return slot
    r = support_row(sa, inst, slot)
    if r >= 0:
        return sa.el_prim[sa.el_i[r, fx.MAP_S] + sa.tri_prim[slot]]
    return sa.el_prim[sa.el_i[sa.inst_aux[inst], fx.MAP_A] + sa.tri_prim[slot]]


@njit(cache=True, error_model="numpy", _nrt=False)
def _feature_normal(sa, inst, prim, u, v):
    """Unit object-space normal (outward of the part) of the feature hit ``prim`` at plane point ``(u, v)`` mm."""
    r, f = feature_row(sa, inst, prim)
    F = sa.el_f[r]
    _, nu, nv, nw = fx.surface(F, sa.el_i[r], sa.el_uv, sa.el_face, f, u, v)
    return (nu * F[fx.U_X] + nv * F[fx.V_X] + nw * F[fx.N_X],
            nu * F[fx.U_X + 1] + nv * F[fx.V_X + 1] + nw * F[fx.N_X + 1],
            nu * F[fx.U_X + 2] + nv * F[fx.V_X + 2] + nw * F[fx.N_X + 2])


@njit(cache=True, error_model="numpy", _nrt=False)
def normal(sa, inst, slot, u, v):
    """Geometric normal of the hit: the triangle's, or the feature's at ``(u, v)``."""
    if slot < -1:
        return _feature_normal(sa, inst, slot, u, v)
    return mesh.object_normal(sa, 0, slot)


@njit(cache=True, error_model="numpy", inline="always")
def part_row(sa, inst, prim):
    """``(row, local)`` of the part's triangle ``prim``: the row whose support holds it and its index there, or
    ``(-1, its index in the rest)``."""
    r0 = sa.inst_aux[inst]
    code = sa.el_prim[sa.el_i[r0, fx.MAP_INV] + prim]
    if code >= 0:
        return -1, code
    j = -1 - code
    r = r0 + sa.el_i[r0, fx.PART_N] - 1
    while sa.el_i[r, fx.S_START] > j:
        r -= 1
    return r, j - sa.el_i[r, fx.S_START]


@njit(cache=True, error_model="numpy", inline="always")
def _local(sa, inst, prim):
    """``(geometry, local triangle)`` of the part's triangle ``prim``: in the rest or in one row's support."""
    r, local = part_row(sa, inst, prim)
    if r < 0:
        return sa.inst_geom[inst], local
    return sa.el_i[r, fx.GEOM_S], local


@njit(cache=True, error_model="numpy", _nrt=False)
def shading_normal(sa, inst, prim, u, v):
    """The part's shading normal on a triangle; a feature's own normal (no interpolation) on a feature."""
    if prim < -1:
        nx, ny, nz = _feature_normal(sa, inst, prim, u, v)
        return nx, ny, nz, False
    g, local = _local(sa, inst, prim)
    return mesh.object_shading_normal(sa, g, local, u, v)


@njit(cache=True, error_model="numpy", _nrt=False)
def point(sa, inst, prim, u, v):
    """Object-space point of the hit: on the triangle from barycentrics, on a feature from its plane point (mm)."""
    if prim < -1:
        r, f = feature_row(sa, inst, prim)
        F = sa.el_f[r]
        w, _, _, _ = fx.surface(F, sa.el_i[r], sa.el_uv, sa.el_face, f, u, v)
        s = 1.0 / F[fx.MM]
        return (F[fx.O_X] + s * (u * F[fx.U_X] + v * F[fx.V_X] + w * F[fx.N_X]),
                F[fx.O_X + 1] + s * (u * F[fx.U_X + 1] + v * F[fx.V_X + 1] + w * F[fx.N_X + 1]),
                F[fx.O_X + 2] + s * (u * F[fx.U_X + 2] + v * F[fx.V_X + 2] + w * F[fx.N_X + 2]))
    g, local = _local(sa, inst, prim)
    return mesh.object_point(sa, g, local, u, v)
