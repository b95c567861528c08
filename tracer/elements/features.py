"""The inner tracer of a micro-structured face: which feature a ray meets, where, and the surface there.

Everything here works in the element's frame, in millimetres: ``u``, ``v`` on the support plane (from the support's
corner of smallest u and v), ``w`` along the support's outward normal. A feature's solid ``K`` sits on the plane at
its centre ``(cu, cv)``, in ``w' = sign * w`` (``sign`` +1 for a bump, raised out of the part; -1 for a pit, cut into
it), between ``w' = 0`` and its height ``h``; each shape is a module of `tracer.elements.shapes` (dome, pyramid,
prism, corner cube), called through its switches (`tracer.elements.shapes.dispatch`).

The relief's surface is the support plane outside the features' bases plus each ``K``'s boundary above the plane;
the base is no surface (the same material goes on across it for a bump, air for a pit). A ray meets a feature where
it crosses ``K``'s boundary at ``w' > 0``: convex ``K``, so at most twice, found as the interval of the ray inside
``K``'s half-spaces (or sphere) with the face that bounds it. Features are found from the layout by walking the
ray's path over the layout's cells (Amanatides and Woo's 2D DDA), never from a mesh:

- ``GRID``: one feature in each cell of the pitch, centred (``cells start at the face's smallest u and v``);
- ``HEX``: rows ``pv = pitch sqrt(3) / 2`` apart, odd rows shifted by half a pitch (domes);
- ``DENSITY``: a lattice of the pitch whose sites are kept or not (one bit each, `el_bits`);
- ``POINTS``: listed centres (`el_uv`, float32 mm) binned by cell (`el_bin` starts, `el_item` ids);
- ``TRIANGULAR``: triangles of side ``s`` close-packed, cells ``s/2`` by the row height ``H = s sqrt(3)/2``: feature
  ``(i, j)`` centred at ``u = (i + 1) s/2``, ``v = j H + H/3`` pointing to +v where ``i + j`` is even, else turned
  180 degrees about its axis (``v = j H + 2H/3``): every shape is met in its own frame mirrored through its axis
  (`_turned`), so the triangular corner cubes tile the face with no gap.

A mesh feature's face planes are rows of `el_face` (``faces``), one table for all its copies, from row
``I[FACE]``, ``I[NFACE]`` of them (empty for the other shapes).

HEX, POINTS and TRIANGULAR test the 3 x 3 cells around the walked one: their features may cross a cell's edge, by
less than a cell. On a support that is not its u-v box, a feature is there only where its centre's cell of the
outline mask is kept (`_on_outline`, `tracer.elements.outline`; its bits follow the density bits in `el_bits`). The
row columns below index `SceneArrays.el_f` and `el_i` (packed by `tracer.elements.support`).
"""

from __future__ import annotations

import math

import numpy as np

from tracer.elements.shapes.base import half_space
from tracer.elements.shapes.dispatch import shape_covers, shape_interval, shape_surface
from tracer.jit import njit

GRID, HEX, DENSITY, POINTS, TRIANGULAR = 0, 1, 2, 3, 4

# el_f columns (float64): the frame in object space, the scale, the support, the feature, the layout
O_X, U_X, V_X, N_X = 0, 3, 6, 9          # frame origin and unit axes, object space (3 each)
MM = 12                                   # millimetres per object unit
LU, LV = 13, 14                           # the support's extent, mm
A, H, RS, SLOPE = 15, 16, 17, 18          # half base (radius), height, sphere radius, a / h (mm, mm, mm, 1)
CU, CV = 19, 20                           # the layout's cell size, mm
ORG_U, ORG_V = 21, 22                     # the layout's first cell corner, mm
SIGN = 23                                 # +1 bump, -1 pit
FMAT, FRHO = 24, 25                       # the features' own surface (-1: the part's material; 0 black;
                                          # 1 Lambertian of reflectance FRHO)
MASK_H = 26                               # the outline mask's cell, mm
FILL_U0, FILL_V0, FILL_DU, FILL_DV = 27, 28, 29, 30   # a tabulated density map's fill map: first cell corner, cell, mm
TAB_MUC = 31                              # a tabulated BSDF's solid side: |cos| of its critical angle (TAB_SPLIT > 0)
NF = 32
MAT_PART, MAT_BLACK, MAT_LAMBERTIAN = -1, 0, 1
# el_i columns (int64)
SHAPE, LAYOUT, NU, NV = 0, 1, 2, 3        # feature shape, layout kind, cells along u and v
GEOM_S = 4                                # the support's own geometry (bottom level) in the store
MAP_A, MAP_S, MAP_INV = 5, 6, 7           # offsets in el_prim: rest -> part, support -> part, part -> either
BITS, UV, BINS = 8, 9, 10                 # offsets in el_bits (bytes), el_uv (rows), el_bin (starts)
ITEMS = 11                                # offset in el_item
MODEL, TAB, TAB_MU, TAB_PHI = 12, 13, 14, 15   # 0 exact, 1 bsdf, 2 grating: its table's first row in el_tab, its
                                               # bins (bsdf); a grating's sizes are in its table (`diffraction`)
FACE, NFACE = 16, 17                           # the feature's face planes: first row in el_face, count (a mesh's)
MASK, MASK_NU, MASK_NV = 18, 19, 20            # a support that is not its u-v box: its kept cells' first byte in
                                               # el_bits and their count along u and v (0: no mask)
LEVELS, FILL, FILL_NU, FILL_NV = 21, 22, 23, 24   # a tabulated BSDF's tables, one per fill level evenly spaced from 0
                                                  # to 1 (1: a periodic layout's one table), and a density map's fill
                                                  # map: its first entry in el_tab (row-major) and cells along u, v
TAB_SPLIT = 25                                    # its solid side's |cos| bins below TAB_MUC (0: uniform bins)
PART_N, PART_K, S_START = 26, 27, 28              # the part's rows (its elements, consecutive rows from
                                                  # `inst_aux`), this row's place among them, its support's first
                                                  # triangle in the part's supports taken in row order (MAP_INV)
NI = 29
EXACT, BSDF, GRATING = 0, 1, 2
#: The most elements one part carries (on disjoint supports). A feature hit's slot is ``-2 - (f * PART_ROWS + k)``:
#: feature ``f`` of the part's row ``k`` (`tracer.kinds.relief`).
PART_ROWS = 8

NEAR = 1.0e300


@njit(cache=True, error_model="numpy", inline="always")
def _clip(o, d, lo_b, hi_b, lo, hi):
    """The part of ``(lo, hi)`` where ``o + t d`` lies in ``[lo_b, hi_b]``."""
    if d == 0.0:
        if o < lo_b or o > hi_b:
            return 1.0, 0.0
        return lo, hi
    t0 = (lo_b - o) / d
    t1 = (hi_b - o) / d
    if t0 > t1:
        t0, t1 = t1, t0
    return max(lo, t0), min(hi, t1)


@njit(cache=True, error_model="numpy", _nrt=False)
def cross_feature(shape, a, h, rs, slope, P, cu, cv, ou, ov, ow, du, dv, dw, t_lo, t_hi):
    """The first ``t`` in ``(t_lo, t_hi)`` where the ray (in ``w'``) crosses the boundary of the feature centred at
    ``(cu, cv)`` above its base; ``inf`` where it does not."""
    lo, hi = shape_interval(shape, a, h, rs, slope, P, cu, cv, ou, ov, ow, du, dv, dw)
    lo2, hi2, lo_base, hi_base = half_space(0.0, 0.0, -1.0, 0.0, ou, ov, ow, du, dv, dw, lo, hi)   # w' >= 0
    if not lo2 < hi2:
        return math.inf
    if not lo_base and t_lo < lo2 < t_hi:
        return lo2
    if not hi_base and t_lo < hi2 < t_hi:
        return hi2
    return math.inf


@njit(cache=True, error_model="numpy", _nrt=False)
def center(F, I, uv, f):
    """Centre ``(cu, cv)`` (mm) of feature ``f`` (its index in the layout)."""
    lay = I[LAYOUT]
    if lay == POINTS:
        q = I[UV] + f
        return np.float64(uv[q, 0]), np.float64(uv[q, 1])
    nu = I[NU]
    j = f // nu
    i = f - j * nu
    if lay == HEX:
        return (i + 0.5 + 0.5 * (j & 1)) * F[CU], (j + 0.5) * F[CV]
    if lay == TRIANGULAR:
        return (i + 1.0) * F[CU], (j + (2.0 if (i + j) & 1 else 1.0) / 3.0) * F[CV]
    return F[ORG_U] + (i + 0.5) * F[CU], F[ORG_V] + (j + 0.5) * F[CV]


@njit(cache=True, error_model="numpy", inline="always")
def _turned(I, f):
    """Whether feature ``f`` is turned 180 degrees about its axis (a TRIANGULAR layout's odd sites)."""
    if I[LAYOUT] != TRIANGULAR:
        return False
    j = f // I[NU]
    return ((f - j * I[NU]) + j) & 1 == 1


@njit(cache=True, error_model="numpy", inline="always")
def _kept(I, bits, i, j):
    """Whether lattice site (i, j) holds a feature (the layouts without bits: always)."""
    if I[LAYOUT] != DENSITY:
        return True
    s = I[BITS] * 8 + j * I[NU] + i
    return (bits[s >> 3] >> (s & 7)) & 1 == 1


@njit(cache=True, error_model="numpy", inline="always")
def _on_outline(F, I, bits, cu, cv):
    """Whether a feature centred at (cu, cv) lies wholly on a support that is not its u-v box (its outline mask's
    cell is kept: `tracer.elements.outline`); always, on a support without a mask."""
    if I[MASK_NU] == 0:
        return True
    i = int(math.floor(cu / F[MASK_H]))
    j = int(math.floor(cv / F[MASK_H]))
    if i < 0 or j < 0 or i >= I[MASK_NU] or j >= I[MASK_NV]:
        return False
    s = I[MASK] * 8 + j * I[MASK_NU] + i
    return (bits[s >> 3] >> (s & 7)) & 1 == 1


@njit(cache=True, error_model="numpy", inline="always")
def _inside(F, cu, cv):
    """Whether a HEX feature at (cu, cv) lies wholly on the support (its odd rows may run over the far edge)."""
    a = F[A]
    return cu - a >= 0.0 and cu + a <= F[LU] and cv - a >= 0.0 and cv + a <= F[LV]


@njit(cache=True, error_model="numpy", _nrt=False)
def _cell(F, I, bits, uv, bins, items, P, i, j, ou, ov, ow, du, dv, dw, lo, best, bf, pu, pv, probe):
    """Test the features of cell (i, j) (and its neighbours for HEX, POINTS and TRIANGULAR): with ``probe``, whether
    one covers the plane point (pu, pv) (returns its index as ``bf``); otherwise the nearest crossing in
    ``(lo, best)``. ``P``: the row's face planes (a mesh feature's)."""
    lay = I[LAYOUT]
    nu = I[NU]
    nv = I[NV]
    shape = I[SHAPE]
    reach = 1 if (lay == HEX or lay == POINTS or lay == TRIANGULAR) else 0
    for jj in range(j - reach, j + reach + 1):
        if jj < 0 or jj >= nv:
            continue
        for ii in range(i - reach, i + reach + 1):
            if ii < 0 or ii >= nu:
                continue
            first = 0
            last = 1
            if lay == POINTS:
                b = I[BINS] + jj * nu + ii
                first = bins[b]
                last = bins[b + 1]
            elif not _kept(I, bits, ii, jj):
                continue
            for k in range(first, last):
                f = items[I[ITEMS] + k] if lay == POINTS else jj * nu + ii
                cu, cv = center(F, I, uv, f)
                if (lay == HEX and not _inside(F, cu, cv)) or not _on_outline(F, I, bits, cu, cv):
                    continue
                turn = -1.0 if _turned(I, f) else 1.0   # met in its own frame, mirrored through its axis
                if probe:
                    if shape_covers(shape, F[A], P, turn * (pu - cu), turn * (pv - cv)):
                        return best, f
                    continue
                t = cross_feature(shape, F[A], F[H], F[RS], F[SLOPE], P, cu, cv, cu + turn * (ou - cu),
                                  cv + turn * (ov - cv), ow, turn * du, turn * dv, dw, lo, best)
                if t < best:
                    best = t
                    bf = f
    return best, bf


@njit(cache=True, error_model="numpy", _nrt=False)
def feature_at(F, I, bits, uv, bins, items, faces, pu, pv):
    """The feature whose base covers the plane point ``(pu, pv)`` (mm), -1 where none does."""
    i = int(math.floor((pu - F[ORG_U]) / F[CU]))
    j = int(math.floor((pv - F[ORG_V]) / F[CV]))
    P = faces[I[FACE]:I[FACE] + I[NFACE]]
    _, f = _cell(F, I, bits, uv, bins, items, P, i, j, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1, pu, pv, True)
    return f


@njit(cache=True, error_model="numpy", _nrt=False)
def search(F, I, bits, uv, bins, items, faces, ou, ov, ow, du, dv, dw, t_lo, t_hi):
    """``(t, f)``: the nearest crossing in ``(t_lo, t_hi)`` of the ray (frame, mm; ``w``, not ``w'``) with a
    feature, and the feature's index; ``(inf, -1)`` where it meets none. Walks the layout's cells along the ray from
    where it enters the features' slab, and stops at the first cell that starts beyond the best crossing."""
    sign = F[SIGN]
    ow = sign * ow
    dw = sign * dw
    lo, hi = _clip(ow, dw, 0.0, F[H], t_lo, t_hi)
    cu = F[CU]
    cv = F[CV]
    nu = I[NU]
    nv = I[NV]
    reach = 1.0 if (I[LAYOUT] == HEX or I[LAYOUT] == POINTS or I[LAYOUT] == TRIANGULAR) else 0.0
    lo, hi = _clip(ou, du, F[ORG_U] - reach * cu, F[ORG_U] + (nu + reach) * cu, lo, hi)
    lo, hi = _clip(ov, dv, F[ORG_V] - reach * cv, F[ORG_V] + (nv + reach) * cv, lo, hi)
    if not lo < hi:
        return math.inf, -1
    su = ou + lo * du - F[ORG_U]
    sv = ov + lo * dv - F[ORG_V]
    i = int(math.floor(su / cu))
    j = int(math.floor(sv / cv))
    step_i = 1 if du > 0.0 else -1
    step_j = 1 if dv > 0.0 else -1
    next_u = ((i + (1 if du > 0.0 else 0)) * cu - (ou - F[ORG_U])) / du if du != 0.0 else math.inf
    next_v = ((j + (1 if dv > 0.0 else 0)) * cv - (ov - F[ORG_V])) / dv if dv != 0.0 else math.inf
    delta_u = cu / abs(du) if du != 0.0 else math.inf
    delta_v = cv / abs(dv) if dv != 0.0 else math.inf
    best = hi
    bf = -1
    P = faces[I[FACE]:I[FACE] + I[NFACE]]
    for _ in range(nu + nv + 4):
        best, bf = _cell(F, I, bits, uv, bins, items, P, i, j, ou, ov, ow, du, dv, dw, t_lo, best, bf, 0.0, 0.0,
                         False)
        leave = min(next_u, next_v)
        if leave >= best or leave >= hi:
            break
        if next_u < next_v:
            i += step_i
            next_u += delta_u
        else:
            j += step_j
            next_v += delta_v
    if bf < 0:
        return math.inf, -1
    return best, bf


@njit(cache=True, error_model="numpy", _nrt=False)
def surface(F, I, uv, faces, f, hu, hv):
    """``(w, nu, nv, nw)`` of feature ``f`` at plane point ``(hu, hv)`` (mm): the relief's height above the plane
    there (``w``, mm, signed: negative in a pit) and its unit normal, outward of the part, in the frame."""
    cu, cv = center(F, I, uv, f)
    a = F[A]
    h = F[H]
    sign = F[SIGN]
    du = hu - cu
    dv = hv - cv
    P = faces[I[FACE]:I[FACE] + I[NFACE]]
    turn = -1.0 if _turned(I, f) else 1.0
    wk, ku, kv, kw = shape_surface(I[SHAPE], a, h, F[RS], F[SLOPE], P, turn * du, turn * dv)
    # K's outward normal in (u, v, w'); the part's outward normal is K's for a bump and the opposite for a pit
    return sign * max(wk, 0.0), sign * turn * ku, sign * turn * kv, kw
