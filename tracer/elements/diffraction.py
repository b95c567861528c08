"""A grating's inner model in the tracer: a ray meeting the element's face leaves in one propagating order.

Issue 52, docs/DESIGN.md "Elements with a wave solution inside". The table of orders (`tracer.elements.grating`) is
packed once per scene into rows of `SceneArrays.el_tab` (`pack`), and `scatter` reads it for each photon that meets
the support of an element whose model is `features.GRATING` (the plain support, as a tabulated BSDF's is: the relief
is far below a ray's resolution):

1. The arrival direction in the grating's frame of the side it comes from: x the (first) grating vector, z into the
   far side. Lit from the ambient, ``z = -n`` (n the support's outward normal); lit from the substrate, the frame
   turned 180 degrees about x, ``z = n`` (the table's second half, solved that way).
2. Folded by the relief's mirror symmetries onto the table's azimuths: y -> -y always; in 2-D lattices also
   x -> -x and, on a square one, x <-> y. Each mirror flips s and keeps p, so an odd number of them turns the Stokes
   vector's S2 and S3 (Mueller diag(1, 1, -1, -1) on either side).
3. One table point chosen at random with the trilinear weights of the ray's wavelength, polar angle and azimuth
   (stochastic interpolation: the expected Mueller matrix is the interpolated one, for one corner's reads).
4. An order chosen with probability (M s)_0, its power for the photon's own normalised Stokes vector s (M_00, the
   unpolarized efficiency, where the scene carries no polarization); 1 - sum of them is absorbed (a metal). Only
   orders that propagate at the photon's own wavelength and direction can be chosen: where one the table point holds
   is cut off there (between table points), its share goes to the others, and the photon is counted
   (`OUTSIDE_TABLE`), as it is where the wavelength or the angle lies outside the table (the nearest point is used).
5. The order's direction from the grating equation (tangential wave vector plus m and n times the grating vectors),
   the state M s / (M s)_0 in the order's (s, p) frame, and the part's medium pushed or popped where it crosses.

The packed block (rows of `el_tab`, width at least max(W, A, Z, 32 K)), from the row ``el_i[r, TAB]``:

=====  ===================================================================================================
0      W, A, Z, K, period x (um), period y (um), n ambient, n substrate, 2-D (0/1), square (0/1), x along v
1..5   wavelengths (nm), polar angles (deg, in the medium light arrives in), azimuths (deg), orders m, orders n
6...   W A Z rows lit from the ambient, then W A Z lit from the substrate, point (w, a, z) at (w A + a) Z + z:
       per side (0 reflected, 1 transmitted) and order k, the 16 elements of its Mueller matrix (row-major) at
       (side K + k) 16; zeros where the order does not propagate at that point
=====  ===================================================================================================

The Mueller matrices are in this tracer's convention (`tracer.optics.polarization`: exp(+i w t), S3 = 2 Im(Ex Ey*))
from the table's Jones matrices, which inkstone answers in exp(-i w t): their complex conjugates are ours.
"""

from __future__ import annotations

import math

import numpy as np

from tracer.elements import features as fx
from tracer.jit import njit
from tracer.optics.polarization import ON, S1, S2, S3, across, rotate_into, set_frame
from tracer.optics.surfaces.base import ABSORBED, CONTINUES, STACK_FULL
from tracer.rng import uniform

HEADER = 6            # rows before the table points
OUTSIDE_TABLE = 3     # a `scatter` status: the photon continues (as `CONTINUES`), counted: the table ran out there
# the Stokes vector (ours) from the coherency vector (Ex Ex*, Ex Ey*, Ey Ex*, Ey Ey*)
_A = np.array([[1, 0, 0, 1], [1, 0, 0, -1], [0, 1, 1, 0], [0, -1j, 1j, 0]])


def mueller(jones: np.ndarray) -> np.ndarray:
    """Mueller matrices (..., 4, 4) of Jones matrices (..., 2, 2) given in the exp(+i w t) convention (our Stokes
    vectors); NaN Jones matrices (an order that does not propagate) give zeros."""
    j = np.nan_to_num(np.asarray(jones, np.complex128))
    kron = np.einsum("...ij,...kl->...ikjl", j, j.conj()).reshape(*j.shape[:-2], 4, 4)
    return np.real(_A @ kron @ np.linalg.inv(_A))


def pack(table) -> np.ndarray:
    """The block of `el_tab` rows of a `tracer.elements.grating.GratingTable` (layout in the module docstring)."""
    body = table.body
    two_d = isinstance(body["period_um"], list)
    px, py = (body["period_um"] if two_d else (body["period_um"], 1.0))
    grids = (table.wavelength_nm, table.polar_deg, table.azimuth_deg)
    W, A, Z = (len(x) for x in grids)
    K = len(table.orders)
    width = max(W, A, Z, 32 * K, 11)
    out = np.zeros((HEADER + 2 * W * A * Z, width))
    out[0, :11] = (W, A, Z, K, px, py, body["ambient_ior"], body["substrate_ior"], float(two_d),
                   float(two_d and px == py), float(not two_d and body.get("grooves_along") == "u"))
    for i, x in enumerate((*grids, table.orders[:, 0], table.orders[:, 1])):
        out[1 + i, :len(x)] = x
    for half, tab in enumerate((table, table.inside)):
        # ours are the conjugates of inkstone's (module docstring)
        m = mueller(np.conj(tab.jones))                    # (W, A, Z, 2, K, 4, 4)
        rows = m.reshape(W * A * Z, 2 * K * 16)
        out[HEADER + half * W * A * Z:HEADER + (half + 1) * W * A * Z, :2 * K * 16] = rows
    return out


def diattenuation(table) -> float:
    """The largest diattenuation sqrt(M01² + M02² + M03²) / M00 of any order holding at least 1e-4 of the light, lit
    from either side: how strongly the grating can polarize (`tracer.effects`). Kept per element id."""
    if table.id in _DIATTENUATION:
        return _DIATTENUATION[table.id]
    worst = 0.0
    for tab in (table, table.inside):
        m = mueller(np.conj(tab.jones))
        m00 = m[..., 0, 0]
        keep = m00 > 1e-4
        if keep.any():
            worst = max(worst, float((np.linalg.norm(m[..., 0, 1:], axis=-1)[keep] / m00[keep]).max()))
    if len(_DIATTENUATION) > 256:
        _DIATTENUATION.clear()
    _DIATTENUATION[table.id] = min(worst, 1.0)
    return _DIATTENUATION[table.id]


_DIATTENUATION: dict[str, float] = {}


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _cell(T, row, n, x):
    """(i, t, outside): `x` between grid values i and i + 1 of row `row` (n ascending values) at fraction t, clamped
    to the grid (outside: it lay beyond it by more than 1e-9 of its span)."""
    lo = T[row, 0]
    hi = T[row, n - 1]
    if n == 1:
        return 0, 0.0, abs(x - lo) > 1e-6 * max(1.0, abs(lo))
    tol = 1e-9 * (hi - lo)
    if x <= lo:
        return 0, 0.0, x < lo - tol
    if x >= hi:
        return n - 2, 1.0, x > hi + tol
    a = 0
    b = n - 1
    while b - a > 1:
        c = (a + b) // 2
        if T[row, c] <= x:
            a = c
        else:
            b = c
    return a, (x - T[row, a]) / (T[row, a + 1] - T[row, a]), False


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _pick(i, t, n, key, dim):
    """Grid index i or i + 1, the latter with probability t (stochastic linear interpolation)."""
    if n > 1 and uniform(key, dim) < t:
        return i + 1
    return i


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _unfold(x, y, my, mx, dg):
    """A folded grating-frame (x, y) back to the ray's own: the mirrors undone in reverse order."""
    if dg:
        x, y = y, x
    if mx:
        x = -x
    if my:
        y = -y
    return x, y


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def in_support(sa, r, inst, dx, dy, dz):
    """(du, dv, dn, |d'|): a world direction d in the (u, v, n) frame of element row `r`'s support on instance
    `inst` (through its object frame, so not unit where the instance is scaled), and its length there."""
    F = sa.el_f[r]
    R = sa.object_from_world[inst]
    ax = R[0, 0] * dx + R[0, 1] * dy + R[0, 2] * dz
    ay = R[1, 0] * dx + R[1, 1] * dy + R[1, 2] * dz
    az = R[2, 0] * dx + R[2, 1] * dy + R[2, 2] * dz
    du = ax * F[fx.U_X] + ay * F[fx.U_X + 1] + az * F[fx.U_X + 2]
    dv = ax * F[fx.V_X] + ay * F[fx.V_X + 1] + az * F[fx.V_X + 2]
    dn = ax * F[fx.N_X] + ay * F[fx.N_X + 1] + az * F[fx.N_X + 2]
    return du, dv, dn, math.sqrt(du * du + dv * dv + dn * dn)


@njit(cache=True, error_model="numpy", _nrt=False)
def scatter(sa, r, inst, dx, dy, dz, med, depth, key, dim, lam, pol):
    """A photon of wavelength `lam` nm arriving along world direction d on the support of grating row `r` (module
    docstring); returns ``(status, dx, dy, dz, f, depth, dim)`` as a surface kind's `scatter` does, with status
    `OUTSIDE_TABLE` for a photon that continues where the table ran out."""
    F = sa.el_f[r]
    T = sa.el_tab
    h = sa.el_i[r, fx.TAB]
    du, dv, dn, norm = in_support(sa, r, inst, dx, dy, dz)
    du, dv, dn = du / norm, dv / norm, dn / norm
    nW, nA, nZ, K = int(T[h, 0]), int(T[h, 1]), int(T[h, 2]), int(T[h, 3])
    px, py, n_amb, n_sub = T[h, 4], T[h, 5], T[h, 6], T[h, 7]
    two_d, square, x_along_v = T[h, 8] != 0.0, T[h, 9] != 0.0, T[h, 10] != 0.0
    inside = dn > 0.0                        # travelling out of the part: lit from the substrate
    n_in, n_far = (n_sub, n_amb) if inside else (n_amb, n_sub)
    # the grating frame of the lit side, in (u, v, n): x, z = -n (ambient) or n (substrate), y = z x x
    gz = 1.0 if inside else -1.0
    gxu, gxv = (0.0, 1.0) if x_along_v else (1.0, 0.0)
    gyu, gyv = -gz * gxv, gz * gxu
    kx = du * gxu + dv * gxv
    ky = du * gyu + dv * gyv
    kz = dn * gz
    # folded onto the table's azimuths by the relief's mirrors
    my = ky < 0.0
    if my:
        ky = -ky
    mx = two_d and kx < 0.0
    if mx:
        kx = -kx
    dg = square and ky > kx
    if dg:
        kx, ky = ky, kx
    parity = my != (mx != dg)
    polar = math.degrees(math.acos(min(1.0, max(0.0, kz))))
    azim = math.degrees(math.atan2(ky, kx))
    wl = lam if lam > 0.0 else T[h + 1, (nW - 1) // 2]
    iw, tw, ow = _cell(T, h + 1, nW, wl)
    ia, ta, oa = _cell(T, h + 2, nA, polar)
    iz, tz, oz = _cell(T, h + 3, nZ, azim)
    outside = ow or oa or oz or lam <= 0.0
    iw = _pick(iw, tw, nW, key, dim)
    ia = _pick(ia, ta, nA, key, dim + 1)
    iz = _pick(iz, tz, nZ, key, dim + 2)
    row = h + HEADER + (nW * nA * nZ if inside else 0) + (iw * nA + ia) * nZ + iz
    W = sa.world_from_object[inst]
    # the table point's values are in its own waves' (s, p) bases: the photon's state is read and handed on in those
    # (lab-frame interpolation: a photon between points keeps its polarization's direction in space, where reading
    # the bases by their labels would turn it by the azimuth between photon and point)
    polarized = pol[ON] != 0.0
    tx = n_in * kx                           # tangential wave vector, units of k0 (folded frame)
    ty = n_in * ky
    zaz = math.radians(T[h + 3, iz])
    sin_g = n_in * math.sin(math.radians(T[h + 2, ia]))
    lam_g = T[h + 1, iw] / 1000.0
    q1 = 0.0
    q2 = 0.0
    q3 = 0.0
    if polarized:
        sx, sy = -math.sin(zaz), math.cos(zaz)   # s = z x k of the point's incidence, at any polar angle
        sx, sy = _unfold(sx, sy, my, mx, dg)
        ex, ey, ez = _world(F, W, gxu, gxv, gyu, gyv, gz, sx, sy, 0.0)
        _, ex, ey, ez = across(dx, dy, dz, ex, ey, ez)
        rotate_into(pol, dx, dy, dz, ex, ey, ez)
        if parity:
            pol[S2] = -pol[S2]
            pol[S3] = -pol[S3]
        q1, q2, q3 = pol[S1], pol[S2], pol[S3]
    lam_um = wl / 1000.0
    total = 0.0
    kept = 0.0
    for j in range(2 * K):
        c = j * 16
        p = T[row, c] + q1 * T[row, c + 1] + q2 * T[row, c + 2] + q3 * T[row, c + 3]
        if p > 0.0:
            total += p
            if _propagates(T, h, j, K, tx, ty, lam_um, px, py, n_in, n_far):
                kept += p
    u = uniform(key, dim + 3)
    if not u < total or not kept > 0.0:
        return ABSORBED, dx, dy, dz, 0.0, depth, dim + 4
    outside = outside or kept < total
    target = u * kept / total
    acc = 0.0
    pick = -1
    for j in range(2 * K):
        c = j * 16
        p = T[row, c] + q1 * T[row, c + 1] + q2 * T[row, c + 2] + q3 * T[row, c + 3]
        if p > 0.0 and _propagates(T, h, j, K, tx, ty, lam_um, px, py, n_in, n_far):
            pick = j
            acc += p
            if target < acc:
                break
    side = pick // K
    k = pick - side * K
    ox = tx + T[h + 4, k] * lam_um / px
    oy = ty + T[h + 5, k] * lam_um / py
    n_out = n_in if side == 0 else n_far
    oz = math.sqrt(max(0.0, n_out * n_out - ox * ox - oy * oy)) * (1.0 if side == 1 else -1.0)
    fx_, fy_ = _unfold(ox, oy, my, mx, dg)
    bx, by, bz = _world(F, W, gxu, gxv, gyu, gyv, gz, fx_, fy_, oz)
    inv = 1.0 / math.sqrt(bx * bx + by * by + bz * bz)
    bx, by, bz = bx * inv, by * inv, bz * inv
    if polarized:
        _apply(pol, T, row, pick * 16, q1, q2, q3, parity)
        sx, sy = _s_axis(sin_g * math.cos(zaz) + T[h + 4, k] * lam_g / px,
                         sin_g * math.sin(zaz) + T[h + 5, k] * lam_g / py, zaz)   # the point's own order
        sx, sy = _unfold(sx, sy, my, mx, dg)
        ex, ey, ez = _world(F, W, gxu, gxv, gyu, gyv, gz, sx, sy, 0.0)
        set_frame(pol, bx, by, bz, ex, ey, ez)
    if side == 1:                            # crossed the face: into the part from the ambient, or out of it
        if not inside:
            if depth == med.shape[0]:
                return STACK_FULL, dx, dy, dz, 0.0, depth, dim + 4
            med[depth] = inst
            depth += 1
        else:
            depth = leave_part(med, depth, inst)
    return (OUTSIDE_TABLE if outside else CONTINUES), bx, by, bz, 1.0, depth, dim + 4


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _propagates(T, h, j, K, tx, ty, lam_um, px, py, n_in, n_far):
    """Whether entry j (side j // K, order j % K) propagates at this wavelength (um) and tangential (tx, ty)."""
    side = j // K
    k = j - side * K
    x = tx + T[h + 4, k] * lam_um / px
    y = ty + T[h + 5, k] * lam_um / py
    n = n_in if side == 0 else n_far
    return x * x + y * y < n * n


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _s_axis(tx, ty, az_rad):
    """(x, y) of s = z x k / |z x k| for a wave of tangential (tx, ty); (-sin az, cos az) for a normal one (the
    table's own convention, `tracer.elements.grating`)."""
    t = math.sqrt(tx * tx + ty * ty)
    if t < 1e-9:
        return -math.sin(az_rad), math.cos(az_rad)
    return -ty / t, tx / t


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _world(F, W, gxu, gxv, gyu, gyv, gz, x, y, z):
    """A grating-frame vector in world space (through the support's (u, v, n) and the instance's transform)."""
    u = x * gxu + y * gyu
    v = x * gxv + y * gyv
    n = z * gz
    bx = u * F[fx.U_X] + v * F[fx.V_X] + n * F[fx.N_X]
    by = u * F[fx.U_X + 1] + v * F[fx.V_X + 1] + n * F[fx.N_X + 1]
    bz = u * F[fx.U_X + 2] + v * F[fx.V_X + 2] + n * F[fx.N_X + 2]
    return (W[0, 0] * bx + W[0, 1] * by + W[0, 2] * bz, W[1, 0] * bx + W[1, 1] * by + W[1, 2] * bz,
            W[2, 0] * bx + W[2, 1] * by + W[2, 2] * bz)


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _apply(pol, T, row, c, q1, q2, q3, parity):
    """The photon's state becomes M s / (M s)_0 for the Mueller matrix at column c of table row `row` (s = (1, q1,
    q2, q3), in the folded frame), handed back in the unfolded one."""
    m0 = T[row, c] + q1 * T[row, c + 1] + q2 * T[row, c + 2] + q3 * T[row, c + 3]
    m1 = T[row, c + 4] + q1 * T[row, c + 5] + q2 * T[row, c + 6] + q3 * T[row, c + 7]
    m2 = T[row, c + 8] + q1 * T[row, c + 9] + q2 * T[row, c + 10] + q3 * T[row, c + 11]
    m3 = T[row, c + 12] + q1 * T[row, c + 13] + q2 * T[row, c + 14] + q3 * T[row, c + 15]
    inv = 1.0 / m0
    sign = -1.0 if parity else 1.0
    pol[S1] = m1 * inv
    pol[S2] = sign * m2 * inv
    pol[S3] = sign * m3 * inv


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def leave_part(med, depth, inst):
    """Pop instance `inst` from the photon's stack of solids (it has left that part); the new depth."""
    for k in range(depth - 1, -1, -1):
        if med[k] == inst:
            for m in range(k, depth - 1):
                med[m] = med[m + 1]
            return depth - 1
    return depth
