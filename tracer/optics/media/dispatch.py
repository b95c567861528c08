"""The medium kinds (kind id = position in `KINDS`): their registration, the switches written out from `KINDS`
(`tracer.jit.kind_switch`), and the Python side that reads a medium's body and packs its row. A new medium kind is
its module (`base` has the contract) and its entry in `KINDS`."""

from __future__ import annotations

import numpy as np

from tracer.jit import kind_switch
from tracer.optics.media import homogeneous
from tracer.optics.spectra import varies
from tracer.optics.surfaces.base import MIE_ROW, N_MPAR, NO_MEDIUM, MaterialError, spec_fields, spec_from_body

KINDS = (homogeneous,)
HOMOGENEOUS = KINDS.index(homogeneous)
KIND_OF = {m.NAME: k for k, m in enumerate(KINDS)}
_MODULE_OF_SPEC = {m.Spec: m for m in KINDS}


def medium_spec(body, name: str = "medium", where: str = "material"):
    """The typed spec of a medium body ``{"type": <kind>, ...}`` (a spec is returned as it is); the parser of a
    solid's ``medium`` field. Raises `MaterialError` naming the field."""
    if type(body) in _MODULE_OF_SPEC:
        return body
    at = f"{where}: {name}"
    if not isinstance(body, dict):
        raise MaterialError(f"{at}: expected a medium body (dict), e.g. {{\"type\": \"homogeneous\", "
                            f"\"absorption_per_m\": 0.5}}, got {type(body).__name__}")
    t = body.get("type")
    if t not in KIND_OF:
        raise MaterialError(f"{at}: unknown medium type {t!r}; known: {sorted(KIND_OF)}")
    return spec_from_body(KINDS[KIND_OF[t]].Spec, str(t), body, at, what="medium")


def module_of(spec):
    """The kind module of a typed medium spec."""
    try:
        return _MODULE_OF_SPEC[type(spec)]
    except KeyError:
        raise MaterialError(f"not a medium spec: {type(spec).__name__}") from None


def host_check(spec, host_ior) -> str | None:
    """What is wrong with medium `spec` inside a solid of index `host_ior` (None: nothing)."""
    return module_of(spec).host_check(spec, host_ior)


def effects_of(spec) -> tuple[str, ...]:
    """The effects a medium calls for (none for None)."""
    return () if spec is None else module_of(spec).effects(spec)


def polarizing_of(spec) -> tuple[int, float]:
    """The polarizing interactions a path meets inside (`tracer.effects.polarization_call`); (0, 0) for None."""
    return (0, 0.0) if spec is None else module_of(spec).polarizing(spec)


def pack_medium(spec, host_ior, tables) -> tuple[int, np.ndarray, np.ndarray]:
    """(medium kind, (N_MPAR,) row, (N_MPAR,) table rows) of a solid's inside: `NO_MEDIUM` for None or a clear
    one. `tables` is the material table's store of values over λ (``add``, ``add_phase``)."""
    row = np.zeros(N_MPAR)
    mtab = np.full(N_MPAR, -1, np.int32)
    row[MIE_ROW] = -1.0
    if spec is None:
        return NO_MEDIUM, row, mtab
    m = module_of(spec)
    row[:] = m.row(spec, host_ior)
    row[MIE_ROW] = -1.0
    for f in spec_fields(type(spec)):   # values over λ that feed a row column (an absorption table)
        v = getattr(spec, f.name)
        if f.metadata.get("mcolumn") is not None and varies(v):
            mtab[f.metadata["mcolumn"]] = tables.add(v.grid())
    for col, values in m.tables(spec, host_ior).items():   # tables only the kind knows how to build
        mtab[col] = tables.add(values)
    rows = m.phase(spec, host_ior)
    if rows is not None:   # a phase function table (Mie)
        row[MIE_ROW] = tables.add_phase(rows)
    return (NO_MEDIUM if m.clear(spec) else KIND_OF[m.NAME]), row, mtab


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
