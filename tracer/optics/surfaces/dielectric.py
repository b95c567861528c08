"""``dielectric``: a solid of refractive index n; its surface is a Fresnel interface, its inside a medium.

| field | type | unit | range | default |
| --- | --- | --- | --- | --- |
| ior | float, Sellmeier or table (`tracer.optics.spectra`) | — | (0, 10] | required |
| absorption_per_m | float or table over λ | 1/m | [0, 1e9] | 0 |
| scattering_per_m | float | 1/m | [0, 1e9] | 0 |
| g | float | — | (−1, 1) | 0 |
| coating | thin films on the surface (`tracer.optics.coating`) | — | — | none |
| fluorescence | inside (`tracer.optics.media.fluorescence`) | — | — | none |
| particles | spheres inside (`tracer.optics.mie`): Mie scattering instead of Henyey–Greenstein | — | — | none |

The geometric normal points outward: a photon arriving against it enters the solid. Reflection is
chosen with the unpolarised Fresnel reflectance (Rs + Rp)/2 of the exact formulas, total internal
reflection where sin θt ≥ 1; n1 = n2 gives exactly zero reflectance and an unchanged direction (no
spurious reflection from rounding). Directions are taken about the interpolated normal where the mesh
has one, about the facet's where that would cross to the wrong side. The index outside is the one of
the solid the photon is in (the medium stack), 1 outside every solid. The inside is a homogeneous
medium (`tracer/optics/media/homogeneous.py`) where σa or σs > 0 or it fluoresces. A coated surface
reflects with the coating's reflectance (transfer matrices, at the photon's wavelength and angle)
instead of Fresnel's; the refracted direction is Snell's between the two outer indices either way.
In a polarized scene (`tracer.optics.polarization`) reflection and refraction act with their Mueller matrices
(s and p, the phase of total internal reflection and of a coating included): the photon reflects with the
probability its own state gives, and leaves polarized.
Effects: `fresnel`, + `absorption` where σa > 0, + `scattering` where σs > 0, + `dispersion` where the
index varies with λ, + `coating`, + `fluorescence`, + `mie` where it holds particles, and `spectral` with
any of the last four or an absorption table. Backward estimator: no.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tracer.jit import njit
from tracer.optics.coating import Coating, coated_reflectance, parse_coating
from tracer.optics.media.dispatch import HOMOGENEOUS
from tracer.optics.media.fluorescence import EMISSION_NM, QY, SIGMA_F, Fluorescence, parse_fluorescence
from tracer.optics.mie import MieTable, Particles, mie_table, packed, parse_particles
from tracer.optics.polarization import ON, enter_plane, interface_power, leave_plane
from tracer.optics.spectra import GRID_N, WHITE_NM, grid_or_value, scalar, varies
from tracer.optics.surfaces.base import (
    CONTINUES,
    N_MPAR,
    NO_MEDIUM,
    SPECULAR,
    STACK_FULL,
    TRANSMITS,
    MaterialError,
    arrival_normal,
    bounds,
    optional,
    param,
    reflect_specular,
    specular_normal,
)
from tracer.optics.thinfilm import stack_mueller
from tracer.rng import uniform

NAME = "dielectric"
FLAGS = SPECULAR | TRANSMITS


@dataclass(frozen=True)
class Spec:
    """Refractive index, and the absorption, scattering and Henyey–Greenstein asymmetry of the inside."""

    ior: Any = field(metadata=bounds(0.0, 10.0, lo_open=True, value="ior", column=0,
                                     doc="refractive index n (dimensionless): a number, {sellmeier: {b, c_um2}} or "
                                         "{table: {nm, n}}"))
    absorption_per_m: Any = field(default=0.0, metadata=bounds(0.0, 1e9, value="spectral", mcolumn=0,
                                                               doc="absorption coefficient σa, 1/m (or a table)"))
    scattering_per_m: float = field(default=0.0, metadata=bounds(0.0, 1e9, doc="scattering coefficient σs, 1/m"))
    g: float = field(default=0.0, metadata=bounds(-1.0, 1.0, lo_open=True, hi_open=True,
                                                  doc="Henyey–Greenstein asymmetry g, dimensionless "
                                                      "(−1 backward, 0 isotropic, 1 forward)"))
    coating: Coating | None = field(default=None, metadata=optional(parse_coating, "thin films, outermost first"))
    fluorescence: Fluorescence | None = field(default=None, metadata=optional(
        parse_fluorescence, "absorption and isotropic re-emission inside"))
    particles: Particles | None = field(default=None, metadata=optional(
        parse_particles, "spheres suspended inside: Mie scattering and absorption at each wavelength"))

    def check(self) -> str | None:
        if self.particles is None:
            return None
        if self.scattering_per_m > 0:
            return ("give either 'scattering_per_m' (Henyey–Greenstein) or 'particles' (Mie), not both: the "
                    "particles scatter with their own phase function")
        try:   # built (or found in the cache) now: its limits are the body's, and the query then finds it ready
            self.mie()
        except MaterialError as exc:
            return str(exc)
        return None

    def mie(self) -> MieTable:
        """The Mie table of the particles in this host (`tracer.optics.mie`, cached by content)."""
        if self.particles is None:
            raise MaterialError("a dielectric without particles has no Mie table")
        host = np.broadcast_to(grid_or_value(self.ior), (GRID_N,))
        return mie_table(self.particles, host, "particles")


def row(spec: Spec) -> np.ndarray:
    return np.array([scalar(spec.ior), 0.0, 0.0, 0.0])


def medium(spec: Spec) -> tuple[int, np.ndarray]:
    m = np.zeros(N_MPAR)
    m[:3] = scalar(spec.absorption_per_m), spec.scattering_per_m, spec.g
    fl = spec.fluorescence
    if fl is not None:
        m[SIGMA_F], m[QY], m[EMISSION_NM] = scalar(fl.absorption_per_m), fl.quantum_yield, fl.emission.mono_nm
    if spec.particles is not None:
        t = spec.mie()
        m[0] += float(np.mean(t.sigma_ext - t.sigma_sca))
        m[1] = float(np.mean(t.sigma_sca))
    clear = (m[0] == 0 and spec.scattering_per_m == 0 and fl is None and not varies(spec.absorption_per_m)
             and spec.particles is None)
    return (NO_MEDIUM if clear else HOMOGENEOUS), m


def medium_tables(spec: Spec) -> dict[int, np.ndarray]:
    """The fluorescence's tables: σf over λ, the emission spectrum's cdf; the particles' σa (with the host's) and
    σs over λ."""
    fl = spec.fluorescence
    out = {}
    if spec.particles is not None:
        t = spec.mie()
        out[0] = grid_or_value(spec.absorption_per_m) + (t.sigma_ext - t.sigma_sca) + np.zeros(GRID_N)
        out[1] = np.array(t.sigma_sca)
    if fl is not None and varies(fl.absorption_per_m):
        out[SIGMA_F] = fl.absorption_per_m.grid()
    if fl is not None and fl.emission.mono_nm == 0:
        out[EMISSION_NM] = fl.emission_cdf()
    return out


def medium_phase(spec: Spec) -> np.ndarray | None:
    """The particles' packed Mie table (`tracer.optics.mie.packed`), None without particles."""
    return None if spec.particles is None else packed(spec.mie())


def polarizing(spec: Spec) -> tuple[int, float]:
    """A solid is entered and left: 2 interfaces, each reflecting pure s at Brewster's angle (diattenuation 1);
    none where n = 1 everywhere and nothing inside scatters with a Mie matrix (`tracer.effects`)."""
    if spec.particles is not None:
        return 2, 1.0
    if not varies(spec.ior) and scalar(spec.ior) == 1.0 and spec.coating is None:
        return 0, 0.0
    return 2, 1.0


def effects(spec: Spec) -> tuple[str, ...]:
    out = ["fresnel"]
    if varies(spec.absorption_per_m) or spec.absorption_per_m > 0:
        out.append("absorption")
    if spec.scattering_per_m > 0:
        out.append("scattering")
    if varies(spec.ior):
        out.append("dispersion")
    if spec.coating is not None:
        out.append("coating")
    if spec.fluorescence is not None:
        out.append("fluorescence")
    if spec.particles is not None:
        out.append("mie")
    if set(out) & {"dispersion", "coating", "fluorescence", "mie"} or varies(spec.absorption_per_m):
        out.append("spectral")
    return tuple(out)


def diffuse_only(spec: Spec) -> bool:
    return False



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


@njit(cache=True, error_model="numpy", _nrt=False)
def scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim, lam, pol):
    u = uniform(key, dim)
    fx, fy, fz = arrival_normal(ngx, ngy, ngz, dx, dy, dz)
    entering = dx * ngx + dy * ngy + dz * ngz < 0.0
    pos = -1
    if entering:
        n1 = param(M, med[depth - 1], 0, lam) if depth > 0 else 1.0
        n2 = param(M, inst, 0, lam)
    else:
        n1 = param(M, inst, 0, lam)
        for k in range(depth - 1, -1, -1):
            if med[k] == inst:
                pos = k
                break
        if pos >= 0:
            n2 = param(M, med[pos - 1], 0, lam) if pos > 0 else 1.0
        elif depth > 0 and med[depth - 1] != inst:
            n2 = param(M, med[depth - 1], 0, lam)   # leaving a solid it was not known to be in
        else:
            n2 = 1.0
    snx, sny, snz = specular_normal(sa, inst, prim, hu, hv, fx, fy, fz)
    cos_i = -(dx * snx + dy * sny + dz * snz)
    polarized = pol[ON] != 0.0
    sx, sy, sz, rs2, rp2, cr, dr, ts2, tp2, ct, dt = snx, sny, snz, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0
    if polarized:   # the Mueller matrices of reflection and transmission, for this photon's own state
        sx, sy, sz = enter_plane(pol, dx, dy, dz, snx, sny, snz)
        rs2, rp2, cr, dr, ts2, tp2, ct, dt = stack_mueller(
            M.layers, M.coat[inst, 0], M.coat[inst, 1] if lam > 0.0 else 0, not entering, n1, n2, 0.0,
            lam if lam > 0.0 else WHITE_NM, min(max(cos_i, 0.0), 1.0))
        pr, pt = interface_power(pol, rs2, rp2), interface_power(pol, ts2, tp2)
        r = pr / (pr + pt) if pr + pt > 0.0 else 1.0
    elif M.coat[inst, 1] > 0 and lam > 0.0:
        r = coated_reflectance(M, inst, entering, n1, n2, 0.0, lam, min(max(cos_i, 0.0), 1.0))
    else:
        r = fresnel_dielectric(cos_i, n1, n2)
    transmitted = False
    if u < r:
        dx, dy, dz = reflect_specular(sa, inst, prim, hu, hv, dx, dy, dz, fx, fy, fz)
    elif n1 == n2:
        transmitted = True   # index-matched: straight on, no spurious bending
    else:
        ok, tx, ty, tz = refract(dx, dy, dz, snx, sny, snz, n1 / n2)
        if not ok or tx * fx + ty * fy + tz * fz >= 0.0:
            ok, tx, ty, tz = refract(dx, dy, dz, fx, fy, fz, n1 / n2)
        if ok:
            dx, dy, dz = tx, ty, tz
            transmitted = True
        else:   # rounding at the critical angle: total internal reflection
            dx, dy, dz = reflect_specular(sa, inst, prim, hu, hv, dx, dy, dz, fx, fy, fz)
    if polarized:
        if transmitted:
            leave_plane(pol, ts2, tp2, ct, dt, dx, dy, dz, sx, sy, sz)
        else:
            leave_plane(pol, rs2, rp2, cr, dr, dx, dy, dz, sx, sy, sz)
    if transmitted:
        if entering:
            if depth == med.shape[0]:
                return STACK_FULL, dx, dy, dz, 0.0, depth, dim + 1
            med[depth] = inst
            depth += 1
        elif pos >= 0:
            for k in range(pos, depth - 1):
                med[k] = med[k + 1]
            depth -= 1
    return CONTINUES, dx, dy, dz, 1.0, depth, dim + 1
