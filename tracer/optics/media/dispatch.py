"""The medium kinds (kind id = position in `KINDS`) and the one switch on a medium kind."""

from __future__ import annotations

from numba import njit

from tracer.optics.media import homogeneous

KINDS = (homogeneous,)
HOMOGENEOUS = KINDS.index(homogeneous)


@njit(cache=True, error_model="numpy", _nrt=False)
def medium_coefficients(M, mi):
    """(σa, σs) in 1/m inside solid `mi`; (0, 0) for a clear one."""
    k = M.medium[mi]
    if k == HOMOGENEOUS:
        return homogeneous.coefficients(M, mi)
    return 0.0, 0.0


@njit(cache=True, error_model="numpy", _nrt=False)
def medium_scatter(M, mi, dx, dy, dz, u1, u2):
    """Unit direction after a scattering event inside solid `mi` (unchanged in a clear one)."""
    if M.medium[mi] == HOMOGENEOUS:
        return homogeneous.scatter(M, mi, dx, dy, dz, u1, u2)
    return dx, dy, dz
