"""Surface models: what a surface does to a photon (or to a backward path) that reaches it.

Kinds, bodies (DESIGN.md) and the parameter row the kernels read:

- `BLACK` ``{"type": "black"}``: absorbs.
- `LAMBERTIAN` ``{"type": "lambertian", "reflectance": ρ}``: (ρ); effect `lambertian`.
- `MIRROR` ``{"type": "mirror", "reflectance": R}``: (R); effect `specular`.
- `MIX` ``{"type": "mix", "diffuse": ρd, "specular": ρs}``: (ρd, ρs); `lambertian`, `specular`.
- `DIELECTRIC` ``{"type": "dielectric", "ior": n, "absorption_per_m": σa, "scattering_per_m": σs,
  "g": g}``: (n, σa, σs, g); effect `fresnel` (+ `absorption`, `scattering` where σ > 0).

Reflectances are fractions in [0, 1], coefficients in 1/m, `g` in (−1, 1). Lambertian and specular
surfaces are two-sided: they reflect on whichever side the light arrives. A dielectric is a solid:
its geometric normal points outward, a ray arriving against the normal enters it.

Fresnel reflectance is the unpolarised average (Rs + Rp)/2 of the exact dielectric formulas, with
total internal reflection when sin θt ≥ 1; n1 = n2 gives exactly zero reflectance and an
unchanged direction (no spurious reflection from rounding).

Everything here that runs in kernels is `@njit(cache=True)`; `pack_materials` turns bodies into the
per-instance table the kernels read.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

BLACK, LAMBERTIAN, MIRROR, MIX, DIELECTRIC = 0, 1, 2, 3, 4
NONE = -1  # no material: a sensor instance or an id the scene does not hold
KIND_OF = {"black": BLACK, "lambertian": LAMBERTIAN, "mirror": MIRROR, "mix": MIX, "dielectric": DIELECTRIC}
N_PAR = 4

_FIELDS = {
    "black": {"type"},
    "lambertian": {"type", "reflectance"},
    "mirror": {"type", "reflectance"},
    "mix": {"type", "diffuse", "specular"},
    "dielectric": {"type", "ior", "absorption_per_m", "scattering_per_m", "g"},
}
_REQUIRED = {"black": set(), "lambertian": {"reflectance"}, "mirror": {"reflectance"},
             "mix": {"diffuse", "specular"}, "dielectric": {"ior"}}


class MaterialError(ValueError):
    """A material body the transport cannot use; the message names the field."""


class MaterialArrays(NamedTuple):
    """Per-instance material table for the kernels.

    kind : (n_inst,) int32 — material kind of each instance id (`NONE` for sensors and unused ids).
    par : (n_inst, 4) float64 — the kind's parameters (see the module table).
    """

    kind: np.ndarray
    par: np.ndarray


def _number(body: dict, key: str, lo: float, hi: float, where: str, default: float | None = None,
            lo_open: bool = False, hi_open: bool = False) -> float:
    if key not in body:
        if default is None:
            raise MaterialError(f"{where}: missing {key!r}")
        return default
    v = body[key]
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise MaterialError(f"{where}: {key!r} must be a finite number, got {v!r}")
    v = float(v)
    if v < lo or v > hi or (lo_open and v == lo) or (hi_open and v == hi):
        lb = "(" if lo_open else "["
        rb = ")" if hi_open else "]"
        raise MaterialError(f"{where}: {key!r} must be in {lb}{lo:g}, {hi:g}{rb}, got {v:g}")
    return v


def material_row(body: dict, where: str = "material") -> tuple[int, np.ndarray]:
    """Validate one material body and return (kind, parameter row (4,) float64).

    Raises
    ------
    MaterialError
        Unknown type, unknown or missing field, value out of range.
    """
    if not isinstance(body, dict):
        raise MaterialError(f"{where}: expected a material body (dict), got {type(body).__name__}")
    t = body.get("type")
    if t not in KIND_OF:
        raise MaterialError(f"{where}: unknown material type {t!r}; known: {sorted(KIND_OF)}")
    extra = set(body) - _FIELDS[t] - {"id", "name"}
    if extra:
        raise MaterialError(f"{where}: unknown field(s) {sorted(extra)} for a {t!r} material")
    missing = _REQUIRED[t] - set(body)
    if missing:
        raise MaterialError(f"{where}: missing field(s) {sorted(missing)} for a {t!r} material")
    par = np.zeros(N_PAR)
    if t == "lambertian" or t == "mirror":
        par[0] = _number(body, "reflectance", 0.0, 1.0, where)
    elif t == "mix":
        par[0] = _number(body, "diffuse", 0.0, 1.0, where)
        par[1] = _number(body, "specular", 0.0, 1.0, where)
        if par[0] + par[1] > 1.0 + 1e-12:
            raise MaterialError(f"{where}: diffuse + specular must be at most 1, got {par[0] + par[1]:g}")
    elif t == "dielectric":
        par[0] = _number(body, "ior", 0.0, 10.0, where, lo_open=True)
        par[1] = _number(body, "absorption_per_m", 0.0, 1e9, where, default=0.0)
        par[2] = _number(body, "scattering_per_m", 0.0, 1e9, where, default=0.0)
        par[3] = _number(body, "g", -1.0, 1.0, where, default=0.0, lo_open=True, hi_open=True)
    return KIND_OF[t], par


def pack_materials(materials: dict[int, dict], default: dict | None, instance_ids: list[int],
                   sensor_ids: set[int]) -> MaterialArrays:
    """The kernels' material table for every instance id up to the largest one.

    Parameters
    ----------
    materials : {instance id: material body}
    default : material body for instances not in `materials`; None means an instance without a
        material is an error.
    instance_ids : the scene's instance ids (sensors included).
    sensor_ids : the ids that are sensors (no material, never hit by `intersect_closest`).
    """
    n = (max(instance_ids) + 1) if instance_ids else 1
    kind = np.full(n, NONE, np.int32)
    par = np.zeros((n, N_PAR))
    known = set(instance_ids)
    for i in materials:
        if not isinstance(i, int | np.integer) or int(i) not in known:
            raise MaterialError(f"materials: instance id {i!r} is not in the scene")
    default_row = material_row(default, "default_material") if default is not None else None
    for i in instance_ids:
        if i in sensor_ids:
            continue
        if i in materials:
            kind[i], par[i] = material_row(materials[i], f"material of instance {i}")
        elif default_row is not None:
            kind[i], par[i] = default_row
        else:
            raise MaterialError(f"instance {i} has no material and no default_material was given")
    return MaterialArrays(kind, par)


# ----------------------------------------------------------------------------------------------------------- kernels


@njit(cache=True)
def fresnel_dielectric(cos_i, n1, n2):
    """Unpolarised Fresnel reflectance for light in medium n1 meeting medium n2.

    cos_i : cosine of the angle of incidence, in [0, 1]. Returns R in [0, 1]; 1 under total
    internal reflection; exactly 0 when n1 == n2.
    """
    if n1 == n2:
        return 0.0
    cos_i = min(max(cos_i, 0.0), 1.0)
    eta = n1 / n2
    sin2_t = eta * eta * max(0.0, 1.0 - cos_i * cos_i)
    if sin2_t >= 1.0:
        return 1.0
    cos_t = math.sqrt(1.0 - sin2_t)
    rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t)
    rp = (n2 * cos_i - n1 * cos_t) / (n2 * cos_i + n1 * cos_t)
    r = 0.5 * (rs * rs + rp * rp)
    return min(max(r, 0.0), 1.0)


@njit(cache=True)
def reflect(dx, dy, dz, nx, ny, nz):
    """Mirror direction of d about the plane with unit normal n (either orientation)."""
    c = 2.0 * (dx * nx + dy * ny + dz * nz)
    return dx - c * nx, dy - c * ny, dz - c * nz


@njit(cache=True)
def refract(dx, dy, dz, nx, ny, nz, eta):
    """Refracted unit direction of unit d through a surface with unit normal n facing against d.

    eta = n1 / n2. Returns (ok, tx, ty, tz); ok is False under total internal reflection.
    """
    cos_i = -(dx * nx + dy * ny + dz * nz)
    sin2_t = eta * eta * max(0.0, 1.0 - cos_i * cos_i)
    if sin2_t >= 1.0:
        return False, dx, dy, dz
    cos_t = math.sqrt(1.0 - sin2_t)
    k = eta * cos_i - cos_t
    tx = eta * dx + k * nx
    ty = eta * dy + k * ny
    tz = eta * dz + k * nz
    inv = 1.0 / math.sqrt(tx * tx + ty * ty + tz * tz)
    return True, tx * inv, ty * inv, tz * inv


@njit(cache=True)
def onb(nx, ny, nz):
    """Two unit vectors completing unit n to a right-handed orthonormal basis (Duff et al. 2017)."""
    s = 1.0 if nz >= 0.0 else -1.0
    a = -1.0 / (s + nz)
    b = nx * ny * a
    return (1.0 + s * nx * nx * a, s * b, -s * nx), (b, s + ny * ny * a, -ny)


@njit(cache=True)
def sample_cosine(nx, ny, nz, u1, u2):
    """A direction about unit n with density cosθ/π (Malley's method). u1, u2 uniform in [0, 1)."""
    r = math.sqrt(u1)
    phi = 2.0 * math.pi * u2
    x = r * math.cos(phi)
    y = r * math.sin(phi)
    z = math.sqrt(max(0.0, 1.0 - u1))
    t, b = onb(nx, ny, nz)
    dx = x * t[0] + y * b[0] + z * nx
    dy = x * t[1] + y * b[1] + z * ny
    dz = x * t[2] + y * b[2] + z * nz
    inv = 1.0 / math.sqrt(dx * dx + dy * dy + dz * dz)
    return dx * inv, dy * inv, dz * inv
