"""Local frames, direction sampling and the tabulated-cdf search shared by every optics family (unit vectors as
float triples)."""

from __future__ import annotations

import math

from tracer.jit import njit


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


@njit(cache=True, _nrt=False)
def find_in_cdf(cdf, lo, n, u):
    """Smallest k in [0, n) with cdf[lo + k] > u (binary search): the entry of a tabulated cdf that u picks."""
    a, b = 0, n - 1
    while a < b:
        mid = (a + b) // 2
        if cdf[lo + mid] > u:
            b = mid
        else:
            a = mid + 1
    return a
