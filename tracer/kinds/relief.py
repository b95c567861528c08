"""Kind 3: a part whose planar support carries an element with an inside (:mod:`tracer.elements`).

The instance's geometry is the part without its support; the support is a geometry of its own (``el_i[GEOM_S]``),
so a ray that misses every feature meets the very triangles, with the very test, it meets without the element. A
ray is traced against the rest, then the support, whose hit counts only outside the features' bases, then the
features near its path (found from the layout, :func:`tracer.elements.features.search`) up to the nearest hit so far.

Results: a triangle hit reports the row ``slot`` of the rest or the support and the *part's* triangle index as its
primitive (so materials, surface tallies and shading normals read as without the element); a feature hit reports
``slot = prim = -2 - f`` (``f`` the feature's index in the layout) and ``(u, v)`` the hit's plane coordinates in mm,
from which :func:`tracer.elements.features.surface` gives its point and normal.
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
    """``(hit, t, slot, u, v)``: the nearest of the rest's hit, the support's outside the bases, and a feature's
    (the whole search also for ``any_hit``: a support hit inside a base is no hit)."""
    r = sa.inst_aux[inst]
    F = sa.el_f[r]
    I = sa.el_i[r]
    hit, t, slot, u, v = traverse_rows(sa.bvh_f, sa.bvh_i, sa.tri_v, sa.geom_node0[sa.inst_geom[inst]],
                                       sa.geom_tri0[sa.inst_geom[inst]], ox, oy, oz, dx, dy, dz, t_max, any_hit,
                                       stack, tstack) if sa.geom_ntri[sa.inst_geom[inst]] > 0 else \
        (False, 0.0, -1, 0.0, 0.0)
    best = t if hit else t_max
    gs = I[fx.GEOM_S]
    hs, ts, ss, us, vs = traverse_rows(sa.bvh_f, sa.bvh_i, sa.tri_v, sa.geom_node0[gs], sa.geom_tri0[gs], ox, oy, oz,
                                       dx, dy, dz, best, False, stack, tstack)
    if I[fx.MODEL] != fx.EXACT:   # a table (bsdf, grating): the plain support, scattered by it (`dispatch`)
        if hs:
            return True, ts, ss, us, vs
        return hit, t, slot, u, v
    ou, ov, ow, du, dv, dw = _to_frame(F, ox, oy, oz, dx, dy, dz)
    if hs and fx.feature_at(F, I, sa.el_bits, sa.el_uv, sa.el_bin, sa.el_item, sa.el_face, ou + ts * du,
                            ov + ts * dv) < 0:
        hit, t, slot, u, v = True, ts, ss, us, vs
        best = ts
    tf, f = fx.search(F, I, sa.el_bits, sa.el_uv, sa.el_bin, sa.el_item, sa.el_face, ou, ov, ow, du, dv, dw, 0.0,
                      best)
    if f >= 0:
        return True, tf, -2 - f, ou + tf * du, ov + tf * dv
    return hit, t, slot, u, v


@njit(cache=True, error_model="numpy", inline="always")
def _on_support(sa, I, slot):
    gs = I[fx.GEOM_S]
    return sa.geom_tri0[gs] <= slot < sa.geom_tri0[gs] + sa.geom_ntri[gs]


@njit(cache=True, error_model="numpy", _nrt=False)
def primitive(sa, inst, slot):
    """The part's triangle index of a triangle hit; ``slot`` itself (``-2 - f``) for a feature's."""
    if slot < -1:
        return slot
    I = sa.el_i[sa.inst_aux[inst]]
    if _on_support(sa, I, slot):
        return sa.el_prim[I[fx.MAP_S] + sa.tri_prim[slot]]
    return sa.el_prim[I[fx.MAP_A] + sa.tri_prim[slot]]


@njit(cache=True, error_model="numpy", _nrt=False)
def _feature_normal(sa, inst, f, u, v):
    """Unit object-space normal (outward of the part) of feature ``f`` at plane point ``(u, v)`` mm."""
    r = sa.inst_aux[inst]
    F = sa.el_f[r]
    _, nu, nv, nw = fx.surface(F, sa.el_i[r], sa.el_uv, sa.el_face, f, u, v)
    return (nu * F[fx.U_X] + nv * F[fx.V_X] + nw * F[fx.N_X],
            nu * F[fx.U_X + 1] + nv * F[fx.V_X + 1] + nw * F[fx.N_X + 1],
            nu * F[fx.U_X + 2] + nv * F[fx.V_X + 2] + nw * F[fx.N_X + 2])


@njit(cache=True, error_model="numpy", _nrt=False)
def normal(sa, inst, slot, u, v):
    """Geometric normal of the hit: the triangle's, or the feature's at ``(u, v)``."""
    if slot < -1:
        return _feature_normal(sa, inst, -2 - slot, u, v)
    return mesh.object_normal(sa, 0, slot)


@njit(cache=True, error_model="numpy", inline="always")
def _local(sa, inst, prim):
    """``(geometry, local triangle)`` of the part's triangle ``prim``: in the rest or in the support."""
    I = sa.el_i[sa.inst_aux[inst]]
    code = sa.el_prim[I[fx.MAP_INV] + prim]
    if code >= 0:
        return sa.inst_geom[inst], code
    return I[fx.GEOM_S], -1 - code


@njit(cache=True, error_model="numpy", _nrt=False)
def shading_normal(sa, inst, prim, u, v):
    """The part's shading normal on a triangle; a feature's own normal (no interpolation) on a feature."""
    if prim < -1:
        nx, ny, nz = _feature_normal(sa, inst, -2 - prim, u, v)
        return nx, ny, nz, False
    g, local = _local(sa, inst, prim)
    return mesh.object_shading_normal(sa, g, local, u, v)


@njit(cache=True, error_model="numpy", _nrt=False)
def point(sa, inst, prim, u, v):
    """Object-space point of the hit: on the triangle from barycentrics, on a feature from its plane point (mm)."""
    if prim < -1:
        r = sa.inst_aux[inst]
        F = sa.el_f[r]
        w, _, _, _ = fx.surface(F, sa.el_i[r], sa.el_uv, sa.el_face, -2 - prim, u, v)
        s = 1.0 / F[fx.MM]
        return (F[fx.O_X] + s * (u * F[fx.U_X] + v * F[fx.V_X] + w * F[fx.N_X]),
                F[fx.O_X + 1] + s * (u * F[fx.U_X + 1] + v * F[fx.V_X + 1] + w * F[fx.N_X + 1]),
                F[fx.O_X + 2] + s * (u * F[fx.U_X + 2] + v * F[fx.V_X + 2] + w * F[fx.N_X + 2]))
    g, local = _local(sa, inst, prim)
    return mesh.object_point(sa, g, local, u, v)
