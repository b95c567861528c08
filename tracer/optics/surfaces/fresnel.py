"""The Fresnel interface between two clear media: unpolarised reflectance and Snell's refraction, shared by the
`dielectric` kind's smooth surface and by each facet of its rough one (`rough_dielectric`)."""

from __future__ import annotations

import math

from tracer.jit import njit


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
