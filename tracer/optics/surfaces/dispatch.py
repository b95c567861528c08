"""The registration of surface kinds and thin elements: kind id = position in `KINDS`, and the one switch
on a surface kind (`scatter`, `albedo`). Adding a kind: its module, one entry in `KINDS`, one branch in
each switch below.

`scatter` is inlined into the transport kernel (numba's ``inline="always"``), and so is the Lambertian kind's:
a real call per bounce passes the scene's and the materials' tuples, a few hundred words, and made the diffuse
room 1.25x slower than the switch written inline; the other kinds stay calls (they cost a compile each where
inlined, and do more work per call).

Python side: `material_spec` turns a wire body (or a spec) into the kind's typed spec, `pack_materials`
builds the kernels' `MaterialArrays` for every instance id, `effects_of` and `backward_ok` answer from the
specs what the scene calls for.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from tracer.jit import njit
from tracer.optics import mie, spectra
from tracer.optics.coating import Coating
from tracer.optics.elements import diffuser, polarizer, retarder
from tracer.optics.surfaces import black, dielectric, lambertian, microfacet, mirror, mix
from tracer.optics.surfaces.base import (
    ABSORBED,
    MIE_ROW,
    N_MPAR,
    N_PAR,
    NO_MEDIUM,
    NONE,
    MaterialArrays,
    MaterialError,
    spec_from_body,
)

KINDS = (black, lambertian, mirror, mix, dielectric, diffuser, polarizer, retarder, microfacet)
BLACK, LAMBERTIAN, MIRROR, MIX, DIELECTRIC, DIFFUSER, POLARIZER, RETARDER, MICROFACET = range(len(KINDS))
KIND_OF = {m.NAME: k for k, m in enumerate(KINDS)}
_MODULE_OF_SPEC = {m.Spec: m for m in KINDS}


def module_of(spec):
    """The kind module of a typed spec."""
    try:
        return _MODULE_OF_SPEC[type(spec)]
    except KeyError:
        raise MaterialError(f"not a material spec: {type(spec).__name__}") from None


def material_spec(body, where: str = "material"):
    """The typed spec of a material: a spec is returned as it is, a wire body (dict) is validated.

    Raises
    ------
    MaterialError
        Not a dict or spec, unknown type, unknown or missing field, value out of range (naming it).
    """
    if type(body) in _MODULE_OF_SPEC:
        return body
    if not isinstance(body, dict):
        raise MaterialError(f"{where}: expected a material body (dict), got {type(body).__name__}")
    t = body.get("type")
    if t not in KIND_OF:
        raise MaterialError(f"{where}: unknown material type {t!r}; known: {sorted(KIND_OF)}")
    return spec_from_body(KINDS[KIND_OF[t]].Spec, str(t), body, where)


def material_row(body, where: str = "material") -> tuple[int, np.ndarray]:
    """Validate one material and return (kind id, parameter row (N_PAR,) float64)."""
    spec = material_spec(body, where)
    m = module_of(spec)
    return KIND_OF[m.NAME], _row(m, spec)


def _row(m, spec) -> np.ndarray:
    """The kind's parameter row, padded with zeros to N_PAR."""
    out = np.zeros(N_PAR)
    r = m.row(spec)
    out[:len(r)] = r
    return out


def effects_of(specs) -> set[str]:
    """The effects a collection of material specs calls for (`lambertian` is always in the set)."""
    out = {"lambertian"}
    for spec in specs:
        out.update(module_of(spec).effects(spec))
    return out


def polarizing_of(spec) -> tuple[int, float]:
    """How many polarizing interactions a path can meet at one surface of this material, and their largest
    diattenuation (`tracer.effects.polarization_call`): the kind's ``polarizing(spec)``, (0, 0) where it has none."""
    m = module_of(spec)
    return m.polarizing(spec) if hasattr(m, "polarizing") else (0, 0.0)


def backward_ok(specs) -> tuple[bool, str]:
    """Whether the backward estimator can follow every one of these materials, and if not why."""
    for spec in specs:
        m = module_of(spec)
        if not m.diffuse_only(spec):
            return False, f"a {m.NAME!r} surface is not purely diffuse"
    return True, ""


def pack_materials(materials: dict, default, instance_ids: list[int], sensor_ids: set[int]) -> MaterialArrays:
    """The kernels' material table for every instance id up to the largest one.

    Parameters
    ----------
    materials : {instance id: material body or spec}
    default : material for instances not in `materials`; None means an instance without a
        material is an error.
    instance_ids : the scene's instance ids (sensors included).
    sensor_ids : the ids that are sensors (no material, never hit by `intersect_closest`).
    """
    n = (max(instance_ids) + 1) if instance_ids else 1
    kind = np.full(n, NONE, np.int32)
    par = np.zeros((n, N_PAR))
    medium = np.full(n, NO_MEDIUM, np.int32)
    mpar = np.zeros((n, N_MPAR))
    ptab = np.full((n, N_PAR), -1, np.int32)
    mtab = np.full((n, N_MPAR), -1, np.int32)
    coat = np.zeros((n, 2), np.int32)
    mpar[:, MIE_ROW] = -1.0
    known = set(instance_ids)
    for i in materials:
        if not isinstance(i, int | np.integer) or int(i) not in known:
            raise MaterialError(f"materials: instance id {i!r} is not in the scene")
    default_spec = material_spec(default, "default_material") if default is not None else None
    tables = _Tables()
    rows: dict = {}   # spec -> its packed rows: a scene of 100k instances has a handful of materials
    for i in instance_ids:
        if i in sensor_ids:
            continue
        if i in materials:
            spec = material_spec(materials[i], f"material of instance {i}")
        elif default_spec is not None:
            spec = default_spec
        else:
            raise MaterialError(f"instance {i} has no material and no default_material was given")
        if spec not in rows:
            rows[spec] = _rows(spec, tables)
        kind[i], par[i], medium[i], mpar[i], ptab[i], mtab[i], coat[i] = rows[spec]
    return MaterialArrays(kind, par, medium, mpar, ptab, mtab, tables.array(), tables.layer_array(), coat,
                          tables.phase_array())


class _Tables:
    """The spectral tables and coating layers of a material table while it is packed (shared, deduplicated)."""

    def __init__(self):
        self.rows: dict[bytes, int] = {}
        self.layers: list[tuple[float, float]] = []
        self.phase: list[np.ndarray] = []

    def add_phase(self, rows: np.ndarray) -> int:
        """Append a medium's packed Mie rows; their first row's index."""
        first = sum(len(r) for r in self.phase)
        self.phase.append(rows)
        return first

    def phase_array(self) -> np.ndarray:
        return np.concatenate(self.phase) if self.phase else np.zeros((1, mie.N_MU))

    def add(self, values: np.ndarray) -> int:
        key = values.tobytes()
        return self.rows.setdefault(key, len(self.rows))

    def array(self) -> np.ndarray:
        if not self.rows:
            return np.zeros((1, spectra.GRID_N))
        return np.stack([np.frombuffer(k) for k in self.rows])

    def layer_array(self) -> np.ndarray:
        return np.array(self.layers, np.float64).reshape(-1, 2) if self.layers else np.zeros((1, 2))


def _rows(spec, tables: _Tables):
    """(kind id, par, medium kind, mpar, ptab, mtab, coat) of one spec."""
    m = module_of(spec)
    par = _row(m, spec)
    mkind, mpar = m.medium(spec) if hasattr(m, "medium") else (NO_MEDIUM, np.zeros(N_MPAR))
    ptab = np.full(N_PAR, -1, np.int32)
    mtab = np.full(N_MPAR, -1, np.int32)
    coat = np.zeros(2, np.int32)
    for f in dataclasses.fields(spec):
        v = getattr(spec, f.name)
        if spectra.varies(v):
            if f.metadata.get("column") is not None:
                ptab[f.metadata["column"]] = tables.add(v.grid())
            if f.metadata.get("mcolumn") is not None:
                mtab[f.metadata["mcolumn"]] = tables.add(v.grid())
        elif isinstance(v, Coating):
            coat[:] = len(tables.layers), len(v.layers)
            tables.layers.extend(v.layers)
    mpar[MIE_ROW] = -1.0
    if hasattr(m, "medium_tables"):   # tables only the kind knows how to build (an emission spectrum's cdf)
        for col, values in m.medium_tables(spec).items():
            mtab[col] = tables.add(values)
    if hasattr(m, "medium_phase"):    # a phase function table (Mie)
        rows = m.medium_phase(spec)
        if rows is not None:
            mpar[MIE_ROW] = tables.add_phase(rows)
    return KIND_OF[m.NAME], par, mkind, mpar, ptab, mtab, coat


# ----------------------------------------------------------------------------------------- the switch


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim, lam, pol):
    """What the surface of instance `inst` does to a photon of wavelength `lam` nm (0: white) and polarization
    state `pol` (`tracer.optics.polarization`) arriving along d (`base` has the contract)."""
    k = M.kind[inst]
    if k == LAMBERTIAN:
        return lambertian.scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim, lam, pol)
    if k == MIRROR:
        return mirror.scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim, lam, pol)
    if k == MIX:
        return mix.scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim, lam, pol)
    if k == DIELECTRIC:
        return dielectric.scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim, lam, pol)
    if k == DIFFUSER:
        return diffuser.scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim, lam, pol)
    if k == POLARIZER:
        return polarizer.scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim, lam, pol)
    if k == RETARDER:
        return retarder.scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim, lam, pol)
    if k == MICROFACET:
        return microfacet.scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim, lam,
                                  pol)
    return ABSORBED, dx, dy, dz, 0.0, depth, dim   # black, or an id without material


@njit(cache=True, error_model="numpy", _nrt=False)
def albedo(M, inst):
    """Diffuse albedo of a surface the backward estimator follows (only kinds whose `diffuse_only` holds)."""
    k = M.kind[inst]
    if k == LAMBERTIAN:
        return lambertian.albedo(M, inst)
    if k == MIX:
        return mix.albedo(M, inst)
    return 0.0

