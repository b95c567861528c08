"""Light sources in photometric units, packed for the kernels.

Types and body fields (lengths in m, angles in degrees):

- ``point``: position, intensity_cd or flux_lm. Isotropic, Φ = 4π I.
- ``spot``: position, direction, cone_deg, falloff_deg = 0, intensity_cd or flux_lm. cone_deg is
  the half-angle from the axis where the intensity reaches zero; I(θ) = I0 for θ ≤ cone − falloff
  and a smoothstep in cosθ down to 0 at θ = cone; Φ = 2π I0 [(1 − cos θi) + (cos θi − cos θo)/2].
- ``collimated``: origin, direction, radius (disk) or width and height (rectangle, optional up),
  illuminance_lx. A parallel beam with illuminance E across it from an aperture centred on
  `origin`; Φ = E × aperture area.
- ``area``: instances (instance ids), exitance_lm_m2. Lambertian emission from the front side (the
  geometric normal) of every triangle of those instances; Φ = M × area.
- ``goniometric``: position, format ("ies" or "ldt"), data (file text), direction = [0, 0, −1]
  (the luminaire's γ = 0 axis), c0 = [1, 0, 0] (the C = 0 half-plane; only its part across
  `direction` counts; C = 90° lies along c0 × direction, +y by default). The type-C table of
  `tracer.photometry`; an attached light turns with its node because the service turns both axes.

Bodies may also carry `id`, `name` and `attached_to` (kept by the service; ignored here); any
other field is rejected. Photons are emitted with weight Φ_total / N × f, where f = I(ω)/(pdf(ω) Φ_j)
is 1 for exactly sampled sources and stays close to 1 for the goniometric table (cells are chosen
in proportion to their flux).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from tracer.photometry import parse_photometry
from tracer.surfaces import onb

POINT, SPOT, COLLIMATED_DISK, COLLIMATED_RECT, AREA, GONIO = 0, 1, 2, 3, 4, 5
N_LPAR = 20
# columns of the parameter row
P_POS, P_AXIS, P_T, P_B = 0, 3, 6, 9
P_I0, P_COS_OUT, P_COS_IN, P_R, P_H, P_FLUX, P_SOLID = 12, 13, 14, 15, 16, 17, 18

_COMMON = {"id", "name", "attached_to", "type"}
_FIELDS = {
    "point": {"position", "intensity_cd", "flux_lm"},
    "spot": {"position", "direction", "cone_deg", "falloff_deg", "intensity_cd", "flux_lm"},
    "collimated": {"origin", "direction", "radius", "width", "height", "up", "illuminance_lx"},
    "area": {"instances", "exitance_lm_m2", "node"},
    "goniometric": {"position", "format", "data", "direction", "c0"},
}


class LightError(ValueError):
    """A light body the transport cannot use; the message names the light and the field."""


class LightArrays(NamedTuple):
    """Every light of a simulation, for the kernels.

    kind (n,) int32; par (n, 20) float64 (see the P_* columns); cdf (n,) float64: cumulative
    selection probability ∝ flux; flux_total: float (lm) in a (1,) array.
    Goniometric tables (flat, per light offsets in `g_off` (n, 4): c offset, γ offset, candela
    offset, cell offset; `g_n` (n, 2): nc, ng): g_c (rad), g_gamma (rad), g_cd (cd), g_cell_cdf.
    Area emitters: tri (m, 9) world v0, e1, e2 (m); tri_n (m, 3) unit front normals; tri_cdf (m,)
    cumulative area within each light; `a_off` (n, 2): first triangle, count; `a_area` (n,): m².
    """

    kind: np.ndarray
    par: np.ndarray
    cdf: np.ndarray
    flux_total: np.ndarray
    g_off: np.ndarray
    g_n: np.ndarray
    g_c: np.ndarray
    g_gamma: np.ndarray
    g_cd: np.ndarray
    g_cell_cdf: np.ndarray
    tri: np.ndarray
    tri_n: np.ndarray
    tri_cdf: np.ndarray
    a_off: np.ndarray
    a_area: np.ndarray


def _vec(body: dict, key: str, where: str, unit: bool = False) -> np.ndarray:
    if key not in body:
        raise LightError(f"{where}: missing {key!r}")
    try:
        v = np.asarray(body[key], dtype=np.float64)
    except (TypeError, ValueError):
        raise LightError(f"{where}: {key!r} must be 3 numbers, got {body[key]!r}") from None
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise LightError(f"{where}: {key!r} must be 3 finite numbers, got {body[key]!r}")
    if unit:
        n = float(np.linalg.norm(v))
        if not n > 0:
            raise LightError(f"{where}: {key!r} must not be the zero vector")
        v = v / n
    return v


def _num(body: dict, key: str, where: str, lo: float = 0.0, hi: float = math.inf, lo_open: bool = False,
         default: float | None = None) -> float:
    if key not in body or body[key] is None:
        if default is None:
            raise LightError(f"{where}: missing {key!r}")
        return default
    v = body[key]
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise LightError(f"{where}: {key!r} must be a finite number, got {v!r}")
    v = float(v)
    if v < lo or v > hi or (lo_open and v == lo):
        raise LightError(f"{where}: {key!r} must be {'>' if lo_open else '>='} {lo:g} and <= {hi:g}, got {v:g}")
    return v


def _gonio_frame(body: dict, where: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The luminaire's γ = 0 axis, C = 0 axis and C = 90° axis (an orthonormal frame) from its body."""
    nadir = _vec(body, "direction", where, unit=True) if "direction" in body else np.array([0.0, 0.0, -1.0])
    c0 = _vec(body, "c0", where, unit=True) if "c0" in body else np.array([1.0, 0.0, 0.0])
    x = c0 - nadir * float(c0 @ nadir)
    if np.linalg.norm(x) < 1e-9:
        if "c0" in body:
            raise LightError(f"{where}: 'c0' must not be parallel to 'direction'")
        x = np.array([0.0, 1.0, 0.0]) - nadir * nadir[1]  # the default +x is the axis itself: take +y
    x = x / np.linalg.norm(x)
    return nadir, x, np.cross(x, nadir)


def spot_solid_angle(cos_out: float, cos_in: float) -> float:
    """∫ f dΩ of the spot profile (1 inside, smoothstep in cosθ across the falloff), sr."""
    return 2.0 * math.pi * ((1.0 - cos_in) + 0.5 * (cos_in - cos_out))


def _intensity_and_flux(body: dict, where: str, solid_angle: float) -> tuple[float, float]:
    has_i = body.get("intensity_cd") is not None
    has_f = body.get("flux_lm") is not None
    if has_i == has_f:
        raise LightError(f"{where}: give exactly one of 'intensity_cd' and 'flux_lm'")
    if has_i:
        i0 = _num(body, "intensity_cd", where)
        return i0, i0 * solid_angle
    flux = _num(body, "flux_lm", where)
    return flux / solid_angle, flux


def pack_lights(lights: list[dict], scene=None, sensor_ids: frozenset = frozenset()) -> LightArrays:
    """Validate light bodies and pack them.

    Parameters
    ----------
    lights : list of light bodies (world metres).
    scene : tracer.Scene, needed for area lights (their triangles are read in world space).
    sensor_ids : instance ids that are sensors (an area light cannot be one).

    Raises
    ------
    LightError
        Unknown type or field, missing or out-of-range value, zero total flux, an area light on an
        unknown instance, a goniometric file that does not parse (the parser's message).
    """
    if not isinstance(lights, list | tuple) or not lights:
        raise LightError("lights: at least one light is needed")
    n = len(lights)
    kind = np.zeros(n, np.int32)
    par = np.zeros((n, N_LPAR))
    g_off = np.zeros((n, 4), np.int64)
    g_n = np.zeros((n, 2), np.int64)
    a_off = np.zeros((n, 2), np.int64)
    a_area = np.zeros(n)
    g_c, g_g, g_cd, g_cells = [], [], [], []
    tris, tri_ns, tri_cdfs = [], [], []
    offs = [0, 0, 0, 0]
    n_tri = 0
    for j, body in enumerate(lights):
        where = f"light {j}" + (f" ({body.get('id')})" if isinstance(body, dict) and body.get("id") else "")
        if not isinstance(body, dict):
            raise LightError(f"{where}: expected a light body (dict), got {type(body).__name__}")
        t = body.get("type")
        if t not in _FIELDS:
            raise LightError(f"{where}: unknown light type {t!r}; known: {sorted(_FIELDS)}")
        extra = set(body) - _FIELDS[t] - _COMMON
        if extra:
            raise LightError(f"{where}: unknown field(s) {sorted(extra)} for a {t!r} light")
        row = par[j]
        if t == "point":
            kind[j] = POINT
            row[P_POS:P_POS + 3] = _vec(body, "position", where)
            row[P_I0], row[P_FLUX] = _intensity_and_flux(body, where, 4.0 * math.pi)
            row[P_SOLID] = 4.0 * math.pi
        elif t == "spot":
            kind[j] = SPOT
            row[P_POS:P_POS + 3] = _vec(body, "position", where)
            a = _vec(body, "direction", where, unit=True)
            row[P_AXIS:P_AXIS + 3] = a
            cone = _num(body, "cone_deg", where, 0.0, 180.0, lo_open=True)
            fall = _num(body, "falloff_deg", where, 0.0, 180.0, default=0.0)
            if fall > cone:
                raise LightError(f"{where}: 'falloff_deg' ({fall:g}) must not exceed 'cone_deg' ({cone:g})")
            cos_out, cos_in = math.cos(math.radians(cone)), math.cos(math.radians(cone - fall))
            row[P_COS_OUT], row[P_COS_IN] = cos_out, cos_in
            omega = spot_solid_angle(cos_out, cos_in)
            row[P_SOLID] = omega
            row[P_I0], row[P_FLUX] = _intensity_and_flux(body, where, omega)
            tt, bb = onb(a[0], a[1], a[2])
            row[P_T:P_T + 3], row[P_B:P_B + 3] = tt, bb
        elif t == "collimated":
            row[P_POS:P_POS + 3] = _vec(body, "origin", where)
            a = _vec(body, "direction", where, unit=True)
            row[P_AXIS:P_AXIS + 3] = a
            e = _num(body, "illuminance_lx", where)
            row[P_I0] = e
            tt, bb = (np.array(v) for v in onb(a[0], a[1], a[2]))
            if "radius" in body and ("width" in body or "height" in body):
                raise LightError(f"{where}: give either 'radius' (disk) or 'width' and 'height' (rectangle)")
            if "radius" in body:
                kind[j] = COLLIMATED_DISK
                r = _num(body, "radius", where, lo_open=True)
                row[P_R] = r
                row[P_FLUX] = e * math.pi * r * r
            else:
                kind[j] = COLLIMATED_RECT
                w = _num(body, "width", where, lo_open=True)
                h = _num(body, "height", where, lo_open=True)
                if "up" in body:
                    up = _vec(body, "up", where, unit=True)
                    bb = up - a * float(up @ a)
                    if np.linalg.norm(bb) < 1e-9:
                        raise LightError(f"{where}: 'up' must not be parallel to 'direction'")
                    bb = bb / np.linalg.norm(bb)
                    tt = np.cross(bb, a)
                row[P_R], row[P_H] = 0.5 * w, 0.5 * h
                row[P_FLUX] = e * w * h
            row[P_T:P_T + 3], row[P_B:P_B + 3] = tt, bb
        elif t == "goniometric":
            kind[j] = GONIO
            row[P_POS:P_POS + 3] = _vec(body, "position", where)
            row[P_AXIS:P_AXIS + 3], row[P_T:P_T + 3], row[P_B:P_B + 3] = _gonio_frame(body, where)
            fmt = body.get("format")
            data = body.get("data")
            if fmt not in ("ies", "ldt"):
                raise LightError(f"{where}: 'format' must be 'ies' or 'ldt', got {fmt!r}")
            if not isinstance(data, str):
                raise LightError(f"{where}: 'data' must be the file text")
            try:
                ph = parse_photometry(fmt, data)
            except ValueError as exc:
                raise LightError(f"{where}: {exc}") from None
            cells = ph.cell_flux()
            flux = float(cells.sum())
            row[P_FLUX] = flux
            row[P_I0] = ph.max_candela()
            g_off[j] = offs
            g_n[j] = len(ph.c_deg), len(ph.gamma_deg)
            g_c.append(np.radians(ph.c_deg))
            g_g.append(np.radians(ph.gamma_deg))
            g_cd.append(ph.candela.ravel())
            cdf = np.cumsum(cells.ravel())
            g_cells.append(cdf / cdf[-1])
            offs = [offs[0] + len(ph.c_deg), offs[1] + len(ph.gamma_deg), offs[2] + ph.candela.size,
                    offs[3] + cells.size]
        elif t == "area":
            kind[j] = AREA
            m_exit = _num(body, "exitance_lm_m2", where)
            ids = body.get("instances")
            if not isinstance(ids, list | tuple) or not ids:
                raise LightError(f"{where}: an area light needs 'instances', a non-empty list of instance ids")
            if scene is None:
                raise LightError(f"{where}: an area light needs the scene to read its triangles")
            known = set(scene.instances())
            world = []
            for i in ids:
                if isinstance(i, bool) or not isinstance(i, int | np.integer) or int(i) not in known:
                    raise LightError(f"{where}: instance {i!r} is not in the scene")
                if int(i) in sensor_ids:
                    raise LightError(f"{where}: instance {i} is a sensor and cannot emit")
                world.append(_world_triangles(scene, int(i)))
            tri = np.concatenate(world)
            e1, e2 = tri[:, 3:6], tri[:, 6:9]
            cr = np.cross(e1, e2)
            area2 = np.linalg.norm(cr, axis=1)
            keep = area2 > 0
            tri, cr, area2 = tri[keep], cr[keep], area2[keep]
            sign = np.concatenate([np.full(len(w), 1.0) for w in world])[keep]
            if len(tri) == 0:
                raise LightError(f"{where}: the instances have no triangle of non-zero area")
            area = 0.5 * area2
            normals = cr / area2[:, None] * sign[:, None]
            a_total = float(area.sum())
            row[P_I0] = m_exit
            row[P_FLUX] = m_exit * a_total
            a_off[j] = n_tri, len(tri)
            a_area[j] = a_total
            cdf = np.cumsum(area)
            tris.append(tri)
            tri_ns.append(normals)
            tri_cdfs.append(cdf / cdf[-1])
            n_tri += len(tri)
    fluxes = par[:, P_FLUX]
    total = float(fluxes.sum())
    if not total > 0:
        raise LightError("lights: the total flux is zero: nothing to simulate")
    cdf = np.cumsum(fluxes) / total

    def cat(parts, shape=(0,)):
        return np.concatenate(parts) if parts else np.zeros(shape)

    return LightArrays(kind, par, cdf, np.array([total]), g_off, g_n, cat(g_c), cat(g_g), cat(g_cd), cat(g_cells),
                       cat(tris, (0, 9)), cat(tri_ns, (0, 3)), cat(tri_cdfs), a_off, a_area)


def _world_triangles(scene, inst: int) -> np.ndarray:
    """(m, 9) world-space triangles (v0, e1, e2) of one instance; edges of a mirrored instance are
    swapped so that e1 × e2 keeps pointing to the instance's outward side."""
    gid = scene.instance_geometry(inst)
    arrays = scene.geometry_arrays(gid)
    v, tri = np.asarray(arrays[0], np.float64), np.asarray(arrays[1], np.int64)
    m = np.asarray(scene.instance_transform(inst), np.float64)
    w = v @ m[:3, :3].T + m[:3, 3]
    p0, p1, p2 = w[tri[:, 0]], w[tri[:, 1]], w[tri[:, 2]]
    if np.linalg.det(m[:3, :3]) < 0:
        p1, p2 = p2, p1
    return np.concatenate([p0, p1 - p0, p2 - p0], axis=1)


# ----------------------------------------------------------------------------------------------------------- kernels


@njit(cache=True, _nrt=False)
def _find(cdf, lo, n, u):
    """Smallest k in [0, n) with cdf[lo + k] > u (binary search)."""
    a, b = 0, n - 1
    while a < b:
        mid = (a + b) // 2
        if cdf[lo + mid] > u:
            b = mid
        else:
            a = mid + 1
    return a


@njit(cache=True, _nrt=False)
def pick_light(L, u):
    """Index of a light chosen with probability ∝ its flux, and that probability."""
    n = L.cdf.shape[0]
    j = _find(L.cdf, 0, n, u)
    p = L.cdf[j] - (L.cdf[j - 1] if j > 0 else 0.0)
    return j, p


@njit(cache=True, _nrt=False)
def _interval(grid, lo, n, x):
    """Index k in [0, n-2] with grid[lo+k] <= x <= grid[lo+k+1] (clamped)."""
    a, b = 0, n - 2
    while a < b:
        mid = (a + b + 1) // 2
        if grid[lo + mid] <= x:
            a = mid
        else:
            b = mid - 1
    return a


@njit(cache=True, _nrt=False)
def gonio_intensity(L, j, dx, dy, dz):
    """Intensity in cd of goniometric light j toward unit direction d (bilinear in C, γ)."""
    c0, g0, t0 = L.g_off[j, 0], L.g_off[j, 1], L.g_off[j, 2]
    nc, ng = L.g_n[j, 0], L.g_n[j, 1]
    p = L.par[j]
    cos_gam = dx * p[P_AXIS] + dy * p[P_AXIS + 1] + dz * p[P_AXIS + 2]
    gam = math.acos(min(1.0, max(-1.0, cos_gam)))
    c = math.atan2(dx * p[P_B] + dy * p[P_B + 1] + dz * p[P_B + 2], dx * p[P_T] + dy * p[P_T + 1] + dz * p[P_T + 2])
    if c < 0.0:
        c += 2.0 * math.pi
    ic = _interval(L.g_c, c0, nc, c)
    ig = _interval(L.g_gamma, g0, ng, gam)
    ca, cb = L.g_c[c0 + ic], L.g_c[c0 + ic + 1]
    ga, gb = L.g_gamma[g0 + ig], L.g_gamma[g0 + ig + 1]
    tc = (c - ca) / (cb - ca) if cb > ca else 0.0
    tg = (gam - ga) / (gb - ga) if gb > ga else 0.0
    tc = min(1.0, max(0.0, tc))
    tg = min(1.0, max(0.0, tg))
    base = t0 + ic * ng + ig
    i00 = L.g_cd[base]
    i01 = L.g_cd[base + 1]
    i10 = L.g_cd[base + ng]
    i11 = L.g_cd[base + ng + 1]
    return (1 - tc) * (1 - tg) * i00 + (1 - tc) * tg * i01 + tc * (1 - tg) * i10 + tc * tg * i11


@njit(cache=True, _nrt=False)
def spot_profile(L, j, dx, dy, dz):
    """Relative intensity f in [0, 1] of spot light j toward unit direction d."""
    p = L.par[j]
    c = dx * p[P_AXIS] + dy * p[P_AXIS + 1] + dz * p[P_AXIS + 2]
    co, ci = p[P_COS_OUT], p[P_COS_IN]
    if c >= ci:
        return 1.0
    if c <= co:
        return 0.0
    x = (c - co) / (ci - co)
    return x * x * (3.0 - 2.0 * x)


@njit(cache=True, _nrt=False)
def intensity_toward(L, j, dx, dy, dz):
    """Intensity in cd of point-like light j (point, spot, goniometric) toward unit direction d; 0 otherwise."""
    k = L.kind[j]
    if k == POINT:
        return L.par[j, P_I0]
    if k == SPOT:
        return L.par[j, P_I0] * spot_profile(L, j, dx, dy, dz)
    if k == GONIO:
        return gonio_intensity(L, j, dx, dy, dz)
    return 0.0


@njit(cache=True, _nrt=False)
def sample_area_point(L, j, u0, u1, u2):
    """A point on area light j, uniform over its area: (x, y, z, nx, ny, nz) with the front normal."""
    first, count = L.a_off[j, 0], L.a_off[j, 1]
    k = first + _find(L.tri_cdf, first, count, u0)
    su = math.sqrt(u1)
    b1 = 1.0 - su
    b2 = u2 * su
    t = L.tri[k]
    x = t[0] + b1 * t[3] + b2 * t[6]
    y = t[1] + b1 * t[4] + b2 * t[7]
    z = t[2] + b1 * t[5] + b2 * t[8]
    return x, y, z, L.tri_n[k, 0], L.tri_n[k, 1], L.tri_n[k, 2]


@njit(cache=True, _nrt=False)
def sample_emission(L, j, u0, u1, u2, u3, u4):
    """Emit one photon from light j.

    Returns (ox, oy, oz, dx, dy, dz, f, on_surface, nx, ny, nz): origin, unit direction, the weight
    factor f = I(ω) / (pdf(ω) Φ_j) (1 for exactly sampled sources), whether the origin lies on a
    surface (area lights: the caller offsets it along n before tracing) and that surface's normal.
    """
    k = L.kind[j]
    p = L.par[j]
    if k == POINT:
        z = 1.0 - 2.0 * u0
        r = math.sqrt(max(0.0, 1.0 - z * z))
        phi = 2.0 * math.pi * u1
        return p[0], p[1], p[2], r * math.cos(phi), r * math.sin(phi), z, 1.0, False, 0.0, 0.0, 0.0
    if k == SPOT:
        co = p[P_COS_OUT]
        c = 1.0 - u0 * (1.0 - co)
        s = math.sqrt(max(0.0, 1.0 - c * c))
        phi = 2.0 * math.pi * u1
        x, y = s * math.cos(phi), s * math.sin(phi)
        dx = x * p[P_T] + y * p[P_B] + c * p[P_AXIS]
        dy = x * p[P_T + 1] + y * p[P_B + 1] + c * p[P_AXIS + 1]
        dz = x * p[P_T + 2] + y * p[P_B + 2] + c * p[P_AXIS + 2]
        inv = 1.0 / math.sqrt(dx * dx + dy * dy + dz * dz)
        dx, dy, dz = dx * inv, dy * inv, dz * inv
        f = spot_profile(L, j, dx, dy, dz) * 2.0 * math.pi * (1.0 - co) / p[P_SOLID]
        return p[0], p[1], p[2], dx, dy, dz, f, False, 0.0, 0.0, 0.0
    if k == COLLIMATED_DISK or k == COLLIMATED_RECT:
        if k == COLLIMATED_DISK:
            r = p[P_R] * math.sqrt(u0)
            phi = 2.0 * math.pi * u1
            a, b = r * math.cos(phi), r * math.sin(phi)
        else:
            a, b = (2.0 * u0 - 1.0) * p[P_R], (2.0 * u1 - 1.0) * p[P_H]
        ox = p[0] + a * p[P_T] + b * p[P_B]
        oy = p[1] + a * p[P_T + 1] + b * p[P_B + 1]
        oz = p[2] + a * p[P_T + 2] + b * p[P_B + 2]
        return ox, oy, oz, p[P_AXIS], p[P_AXIS + 1], p[P_AXIS + 2], 1.0, False, 0.0, 0.0, 0.0
    if k == AREA:
        x, y, z, nx, ny, nz = sample_area_point(L, j, u0, u1, u2)
        r = math.sqrt(u3)
        phi = 2.0 * math.pi * u4
        a, b = r * math.cos(phi), r * math.sin(phi)
        c = math.sqrt(max(0.0, 1.0 - u3))
        t, bb = onb(nx, ny, nz)
        dx = a * t[0] + b * bb[0] + c * nx
        dy = a * t[1] + b * bb[1] + c * ny
        dz = a * t[2] + b * bb[2] + c * nz
        inv = 1.0 / math.sqrt(dx * dx + dy * dy + dz * dz)
        return x, y, z, dx * inv, dy * inv, dz * inv, 1.0, True, nx, ny, nz
    # goniometric: a cell in proportion to its flux, then uniform in solid angle within it
    c0, g0, e0 = L.g_off[j, 0], L.g_off[j, 1], L.g_off[j, 3]
    nc, ng = L.g_n[j, 0], L.g_n[j, 1]
    ncell = (nc - 1) * (ng - 1)
    cell = _find(L.g_cell_cdf, e0, ncell, u0)
    pc = L.g_cell_cdf[e0 + cell] - (L.g_cell_cdf[e0 + cell - 1] if cell > 0 else 0.0)
    ic = cell // (ng - 1)
    ig = cell - ic * (ng - 1)
    ca, cb = L.g_c[c0 + ic], L.g_c[c0 + ic + 1]
    ga, gb = L.g_gamma[g0 + ig], L.g_gamma[g0 + ig + 1]
    c = ca + u1 * (cb - ca)
    cga, cgb = math.cos(ga), math.cos(gb)
    cg = cga + u2 * (cgb - cga)
    sg = math.sqrt(max(0.0, 1.0 - cg * cg))
    a, b = sg * math.cos(c), sg * math.sin(c)  # along the C = 0 and C = 90° axes; cg along γ = 0
    dx = a * p[P_T] + b * p[P_B] + cg * p[P_AXIS]
    dy = a * p[P_T + 1] + b * p[P_B + 1] + cg * p[P_AXIS + 1]
    dz = a * p[P_T + 2] + b * p[P_B + 2] + cg * p[P_AXIS + 2]
    d_omega = (cb - ca) * (cga - cgb)
    inten = gonio_intensity(L, j, dx, dy, dz)
    f = inten * d_omega / (pc * p[P_FLUX]) if pc > 0.0 else 0.0
    return p[0], p[1], p[2], dx, dy, dz, f, False, 0.0, 0.0, 0.0
