"""``dielectric``: a solid of refractive index n; its surface is a Fresnel interface, smooth or rough, its inside
a medium.

| field | type | unit | range | default |
| --- | --- | --- | --- | --- |
| ior | float, Sellmeier or table (`tracer.optics.spectra`) | — | (0, 10] | required |
| alpha | float: GGX roughness α of the surface (along `axis` where brushed) | — | 0 or [1e-4, 1] | 0 (smooth) |
| alpha_y | float: α across `axis` (anisotropic, brushed) | — | [1e-4, 1] | `alpha` (isotropic) |
| axis | [x, y, z]: the direction of `alpha` in the node's frame (brushing) | — | not zero | a frame of the normal |
| coating | thin films on the surface (on every facet where rough; `tracer.optics.coating`) | — | — | none |
| medium | what fills it: ``{"type": "homogeneous", ...}`` (`tracer/optics/media/`) | — | — | clear |
| absorption_per_m, scattering_per_m, g, fluorescence, particles | DESIGN.md's form of `medium` | | | none |

The geometric normal points outward: a photon arriving against it enters the solid. The index outside is the one of
the solid the photon is in (the medium stack), 1 outside every solid. A smooth surface (α = 0) reflects with the
unpolarised Fresnel reflectance (Rs + Rp)/2 of the exact formulas (`fresnel`), total internal reflection where
sin θt ≥ 1; n1 = n2 gives exactly zero reflectance and an unchanged direction (no spurious reflection from
rounding). Directions are taken about the interpolated normal where the mesh has one, about the facet's where that
would cross to the wrong side. A coated surface reflects with the coating's reflectance (transfer matrices, at the
photon's wavelength and angle) instead of Fresnel's; the refracted direction is Snell's between the two outer
indices either way. A rough surface (α > 0) is a height field of such interfaces, GGX microfacets
(`rough_dielectric`, Walter et al. 2007), as pbrt's dielectric material with a roughness. In a polarized scene
(`tracer.optics.polarization`) reflection and refraction act with their Mueller matrices (s and p, the phase of total
internal reflection and of a coating included): the photon reflects with the probability its own state gives, and
leaves polarized. The inside is a medium of its own kind (absorption, scattering, fluorescence, particles).

The medium is a kind of its own (`tracer/optics/media/`, ``medium``); the design's shorter form, a homogeneous
medium's fields on the dielectric itself, says the same (`filling`), and a body gives one form or the other. The kind
``rough_dielectric`` (a dielectric with ``alpha``), which this kind took in on 2026-12-07, is still read
(`upgrade`).

Effects: `fresnel`, + `dispersion` where the index varies with λ, + `coating`, + the medium's (`absorption`,
`scattering`, `fluorescence`, `mie`), and `spectral` with dispersion, a coating or a medium that needs a wavelength.
Backward estimator: no.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tracer.jit import njit
from tracer.optics.coating import Coating, coated_reflectance, parse_coating
from tracer.optics.elements.base import parse_axis
from tracer.optics.media import dispatch as media
from tracer.optics.media import homogeneous
from tracer.optics.polarization import ON, enter_plane, interface_power, leave_plane
from tracer.optics.spectra import WHITE_NM, scalar, varies
from tracer.optics.surfaces import rough_dielectric
from tracer.optics.surfaces.base import (
    CONTINUES,
    GLOSSY,
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
from tracer.optics.surfaces.fresnel import fresnel_dielectric, refract
from tracer.optics.surfaces.microfacet import ALPHA_MIN
from tracer.optics.thinfilm import stack_mueller
from tracer.rng import uniform

NAME = "dielectric"
FLAGS = SPECULAR | TRANSMITS   # smooth; a rough one's are `flags(spec)`
#: older wire types read as this kind (`upgrade`)
ALIASES = ("rough_dielectric",)
#: a homogeneous medium's fields, which the design's form writes on the dielectric itself
MEDIUM_FIELDS = ("absorption_per_m", "scattering_per_m", "g", "fluorescence", "particles")
ALPHA = 4   # the row's roughness columns: αx, αy, brushing axis (3), axis given (as `microfacet`)


def _medium_field(name: str):
    """A `homogeneous` field written on the dielectric: its rule and meaning, absent by default."""
    meta = dict(next(f for f in dataclasses.fields(homogeneous.Spec) if f.name == name).metadata)
    meta["doc"] = f"{meta['doc']}: the medium inside, in the design's form (or give 'medium')"
    return field(default=None, metadata=meta)


@dataclass(frozen=True)
class Spec:
    """Refractive index, the surface's roughness, a coating, and the medium inside."""

    ior: Any = field(metadata=bounds(0.0, 10.0, lo_open=True, value="ior", column=0,
                                     doc="refractive index n (dimensionless): a number, {sellmeier: {b, c_um2}} or "
                                         "{table: {nm, n}}"))
    alpha: float | None = field(default=None, metadata=bounds(0.0, 1.0, doc=(
        "GGX roughness α of the surface, dimensionless (along `axis` where brushed); 0 or absent: smooth")))
    alpha_y: float | None = field(default=None, metadata=bounds(ALPHA_MIN, 1.0, doc="GGX roughness across `axis`"))
    axis: tuple[float, float, float] | None = field(default=None, metadata=optional(
        parse_axis, "the direction of `alpha` [x, y, z] in the node's frame (brushing)"))
    coating: Coating | None = field(default=None, metadata=optional(parse_coating, "thin films, outermost first"))
    medium: Any = field(default=None, metadata=optional(
        media.medium_spec, "what fills the solid: {type: homogeneous, absorption_per_m, scattering_per_m, g, "
                           "fluorescence, particles}; clear where absent"))
    absorption_per_m: Any = _medium_field("absorption_per_m")
    scattering_per_m: float | None = _medium_field("scattering_per_m")
    g: float | None = _medium_field("g")
    fluorescence: Any = _medium_field("fluorescence")
    particles: Any = _medium_field("particles")

    def check(self) -> str | None:
        alpha = self.alpha or 0.0
        if 0.0 < alpha < ALPHA_MIN:
            return f"'alpha' must be 0 (a smooth surface) or at least {ALPHA_MIN:g}, got {alpha:g}"
        if alpha == 0.0 and (self.alpha_y is not None or self.axis is not None):
            return "'alpha_y' and 'axis' describe a rough surface: give 'alpha' > 0 too"
        flat = [k for k in MEDIUM_FIELDS if getattr(self, k) is not None]
        if flat and self.medium is not None:
            return f"give the medium once: {flat} or 'medium', not both"
        filling = self.filling()
        if filling is None:
            return None
        problem = filling.check() if flat else None   # a medium body was checked when it was read
        return problem or media.host_check(filling, self.ior)

    def filling(self):
        """The medium inside: ``medium``, or the homogeneous one the design's form writes on the dielectric, or
        None (clear)."""
        flat = {k: getattr(self, k) for k in MEDIUM_FIELDS if getattr(self, k) is not None}
        return homogeneous.Spec(**flat) if flat else self.medium


def upgrade(body: dict) -> dict:
    """An older body in today's form: the kind ``rough_dielectric`` read as a dielectric with its ``alpha`` (which it
    requires, > 0)."""
    if body.get("type") not in ALIASES:
        return body
    if "alpha" not in body:
        raise MaterialError(f"missing field(s) ['alpha'] for a {body['type']!r} material")
    if isinstance(body["alpha"], int | float) and not body["alpha"] > 0:
        raise MaterialError(f"'alpha' of a {body['type']!r} must be at least {ALPHA_MIN:g}, got {body['alpha']!r} (a "
                            "smooth surface is a 'dielectric' with 'alpha' 0)")
    return {**body, "type": NAME}


def row(spec: Spec) -> np.ndarray:
    """[n, 0, 0, 0, αx, αy, axis (3), axis given]: the index in column 0 (a solid nested in this one reads it there),
    the roughness where `microfacet` keeps it (zeros where smooth)."""
    if not spec.alpha:
        return np.array([scalar(spec.ior), 0.0, 0.0, 0.0])
    ay = spec.alpha if spec.alpha_y is None else spec.alpha_y
    ax = (0.0, 0.0, 0.0, 0.0) if spec.axis is None else (*spec.axis, 1.0)
    return np.array([scalar(spec.ior), 0.0, 0.0, 0.0, spec.alpha, ay, *ax])


def flags(spec: Spec) -> int:
    """A delta lobe where smooth, a spread one where rough; both transmit."""
    return GLOSSY | TRANSMITS if spec.alpha else FLAGS


def inside(spec: Spec) -> tuple[Any, Any]:
    """(the medium that fills the solid or None, the solid's index: the host of its particles)."""
    return spec.filling(), spec.ior


def polarizing(spec: Spec) -> tuple[int, float]:
    """A solid is entered and left: 2 interfaces (or facets), each reflecting pure s at Brewster's angle
    (diattenuation 1); none where n = 1 everywhere and nothing inside scatters with a Mie matrix
    (`tracer.effects`)."""
    if media.polarizing_of(spec.filling())[0]:
        return 2, 1.0
    if not varies(spec.ior) and scalar(spec.ior) == 1.0 and spec.coating is None:
        return 0, 0.0
    return 2, 1.0


def effects(spec: Spec) -> tuple[str, ...]:
    out = ["fresnel"]
    if varies(spec.ior):
        out.append("dispersion")
    if spec.coating is not None:
        out.append("coating")
    inner = media.effects_of(spec.filling())
    out += [e for e in inner if e != "spectral"]
    if {"dispersion", "coating"} & set(out) or "spectral" in inner:
        out.append("spectral")
    return tuple(out)


def diffuse_only(spec: Spec) -> bool:
    return False


@njit(cache=True, error_model="numpy", _nrt=False)
def scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim, lam, pol):
    if M.par[inst, ALPHA] > 0.0:   # a rough surface: one facet of it
        return rough_dielectric.scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim,
                                        lam, pol)
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
