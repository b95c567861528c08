"""The medium kinds (kind id = position in `KINDS`) and the one switch on a medium kind."""

from __future__ import annotations

from tracer.jit import njit
from tracer.optics.media import homogeneous

KINDS = (homogeneous,)
HOMOGENEOUS = KINDS.index(homogeneous)


@njit(cache=True, error_model="numpy", _nrt=False)
def medium_coefficients(M, mi, lam):
    """(σa, σs, σf) in 1/m inside solid `mi` at λ nm (0: a white photon); zeros for a clear one."""
    k = M.medium[mi]
    if k == HOMOGENEOUS:
        return homogeneous.coefficients(M, mi, lam)
    return 0.0, 0.0, 0.0


@njit(cache=True, error_model="numpy", _nrt=False)
def medium_event(M, mi, dx, dy, dz, lam, sig_s, sig_f, key, dim, pol):
    """An event inside solid `mi` (scattering or fluorescence): (alive, dx, dy, dz, λ, power factor, dim); the
    photon's polarization state `pol` is updated in place (`tracer.optics.polarization`)."""
    if M.medium[mi] == HOMOGENEOUS:
        return homogeneous.event(M, mi, dx, dy, dz, lam, sig_s, sig_f, key, dim, pol)
    return True, dx, dy, dz, lam, 1.0, dim
