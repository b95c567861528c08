"""The medium kinds (kind id = position in `KINDS`) and their switches, written out from `KINDS`
(`tracer.jit.kind_switch`): a new medium kind is its module (`base` has the contract) and its entry in `KINDS`."""

from __future__ import annotations

from tracer.jit import kind_switch
from tracer.optics.media import homogeneous

KINDS = (homogeneous,)
HOMOGENEOUS = KINDS.index(homogeneous)


medium_coefficients = kind_switch(
    "medium_coefficients", "M, mi, lam", "M.medium[mi]", {k: m.coefficients for k, m in enumerate(KINDS)},
    "(0.0, 0.0, 0.0)",   # a clear solid (`NO_MEDIUM`), or an id no kind has
    doc="(σa, σs, σf) in 1/m inside solid `mi` at λ nm (0: a white photon); zeros for a clear one.",
    cache=True, error_model="numpy", _nrt=False)

medium_event = kind_switch(
    "medium_event", "M, mi, dx, dy, dz, lam, sig_s, sig_f, key, dim, pol", "M.medium[mi]",
    {k: m.event for k, m in enumerate(KINDS)}, "(True, dx, dy, dz, lam, 1.0, dim)",
    doc="An event inside solid `mi` (scattering or fluorescence): (alive, dx, dy, dz, λ, power factor, dim); the "
        "photon's polarization state `pol` is updated in place (`tracer.optics.polarization`).",
    cache=True, error_model="numpy", _nrt=False)
