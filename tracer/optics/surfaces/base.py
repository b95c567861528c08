"""The surface contract: what a surface kind does to a photon that reaches it.

A surface kind is one module in this folder (or in `tracer/optics/elements/`, for thin sheets). It holds:

- ``NAME``: the wire `type` (``{"type": NAME, ...}``, docs/DESIGN.md).
- ``Spec``: a frozen dataclass, the kind's typed spec. Its fields are the body's fields; each float field
  carries its range in ``field(metadata=bounds(lo, hi, ...))``, and a parameter table (name, unit,
  range, default) stands in the module docstring. ``Spec.check()`` may add rules across fields.
  `spec_from_body` below builds and validates one from a wire body, for every kind alike.
- ``row(spec) -> (≤ N_PAR,) float64``: the parameter row the kernels read; ``inside(spec)`` (optional, a solid):
  ``(medium spec or None, index of the solid)``, the medium that fills it (a kind of `tracer/optics/media/`,
  packed by `tracer.optics.media.dispatch.pack_medium` into the medium row; None or a clear one: `NO_MEDIUM`).
  A field whose ``bounds(...)`` names a ``column`` (or ``mcolumn``, in a medium's row) may vary with
  the wavelength (``value="spectral"`` or ``"ior"``, `tracer.optics.spectra`): the row holds its
  `spectra.scalar`, and `pack_materials` puts its table beside (``ptab``/``mtab``), read through `param`
  and `mparam` by photons that carry a wavelength. A ``coating`` field (`tracer.optics.coating`) is packed
  into ``layers``/``coat`` the same way.
- ``effects(spec) -> tuple[str, ...]``: the effects it calls for (`tracer.effects.EFFECTS`).
- ``FLAGS``: the lobes the kind may have, as transport asks them (pbrt's BxDF flags; transport never names a
  kind): a sum of `DIFFUSE` (a Lambertian lobe, of the albedo `dispatch.surface_albedo` gives), `GLOSSY` (a spread
  lobe that is not Lambertian), `SPECULAR` (a delta lobe: a mirror, a refraction) and `TRANSMITS` (light may go
  through); 0 for a surface that absorbs everything. Where the flags are exactly `DIFFUSE` the paths from the eye
  sample the lobe themselves (`tracer.transport.radiance`). A kind whose lobes depend on its fields (a dielectric
  is `SPECULAR` when smooth, `GLOSSY` when rough) also has ``flags(spec)``; the kernels read each instance's flags
  from `MaterialArrays.flags`.
- ``upgrade(body) -> body`` and ``ALIASES`` (optional): an older wire body of the kind (or of a kind since folded
  into it, whose `type` is in ``ALIASES``) rewritten in today's form, so that stored scenes keep loading.
- ``diffuse_only(spec) -> bool``: whether the backward estimator can follow it (it reflects only
  diffusely; a black surface is diffuse with albedo 0). A kind that can be diffuse also has the jitted
  ``albedo(M, inst)``, its diffuse albedo, and a branch in `dispatch.albedo` (0 for every other kind).
- the jitted ``scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim, lam, pol)``
  returning ``(status, dx, dy, dz, f, depth, dim)``:

  * ``status``: `CONTINUES` (the photon leaves along the new unit direction d), `ABSORBED`, or
    `STACK_FULL` (it would enter more nested solids than ``med`` holds: the caller counts and drops it);
  * ``f``: the factor its weight (lm) is multiplied by (1 for the analog kinds here, which choose
    reflection with probability ρ instead of scaling the weight);
  * ``med[0:depth]``: instance ids of the solids the photon is inside, innermost last; a kind that
    refracts into or out of a solid pushes or pops it and returns the new ``depth``;
  * ``lam``: the photon's wavelength in nm, 0 for a white photon (then every value is the row's own);
  * ``pol``: the photon's polarization state (`tracer.optics.polarization`), read and updated in place where
    ``pol[ON]`` is 1 (a polarized scene): a kind rotates it into its own frame, applies its Mueller matrix,
    chooses among its outcomes by the power each gives this state, and leaves it in the outgoing frame;
    a diffuse kind depolarizes it. Where ``pol[ON]`` is 0 a kind must not let it change what it does;
  * ``key``, ``dim``: the photon's random stream (`tracer.rng.uniform(key, dim)`); a kind returns ``dim``
    advanced past the numbers it drew.

  The arguments: ``sa`` the scene arrays (`tracer.accel.traverse.SceneArrays`), ``M`` the `MaterialArrays`,
  ``inst, prim, hu, hv`` the hit, ``d`` the unit direction of arrival, ``ng`` the hit's unit geometric
  normal (outward for a solid) in world space.

Reflectances are fractions in [0, 1], lengths in m, coefficients in 1/m. Lambertian and specular
surfaces are two-sided: they reflect on whichever side the light arrives.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import NamedTuple

import numpy as np

from tracer.accel.traverse import shading_normal
from tracer.errors import TracerError
from tracer.jit import njit
from tracer.optics import spectra

DIFFUSE, GLOSSY, SPECULAR, TRANSMITS = 1, 2, 4, 8   # a kind's FLAGS (see above); 0: absorbs everything
N_PAR = 10          # parameter row of a surface (a kind's `row` may be shorter: the rest is zero)
N_MPAR = 8          # parameter row of the medium inside a solid
NONE = -1           # no material: a sensor instance or an id the scene does not hold
NO_MEDIUM = -1      # the inside of a solid that neither absorbs nor scatters (or no solid at all)
MIE_ROW = 6         # medium row column: first row of the medium's Mie table in `MaterialArrays.phase`, −1 if none
ABSORBED, CONTINUES, STACK_FULL = 0, 1, 2


class MaterialError(TracerError):
    """A material body the transport cannot use; the message names the field."""


class MaterialArrays(NamedTuple):
    """Per-instance material table for the kernels.

    kind : (n_inst,) int32 — surface kind of each instance id (`NONE` for sensors and unused ids).
    par : (n_inst, N_PAR) float64 — the kind's parameter row.
    medium : (n_inst,) int32 — medium kind inside the instance's solid (`NO_MEDIUM` if none).
    mpar : (n_inst, N_MPAR) float64 — the medium's parameter row.
    ptab, mtab : (n_inst, N_PAR), (n_inst, N_MPAR) int32 — the row of `tables` that replaces a column for a
        photon with a wavelength, −1 where the column does not vary with it.
    tables : (n_tables, spectra.GRID_N) float64 — values on the wavelength grid (`tracer.optics.spectra`).
    layers : (n_layers, 2) float64 — thin-film layers [n, thickness nm] of every coating, outermost first.
    coat : (n_inst, 2) int32 — first layer and layer count of the instance's coating (count 0: none).
    phase : (n_rows, mie.N_MU) float64 — the packed Mie tables of every particle medium (`tracer.optics.mie.packed`);
        a medium's first row is its row's column `MIE_ROW` (−1: no particles, Henyey–Greenstein).
    flags : (n_inst,) int64 — the lobes of each instance's surface (the kind's ``FLAGS``, or ``flags(spec)``).
    scatter_at : (n_kinds,) int64 — the address of each kind's ``scatter`` in this process, filled by
        `tracer.optics.surfaces.dispatch.bind` before a CPU kernel runs (zeros as packed and shipped: an address
        means nothing in another process).
    """

    kind: np.ndarray
    par: np.ndarray
    medium: np.ndarray
    mpar: np.ndarray
    ptab: np.ndarray
    mtab: np.ndarray
    tables: np.ndarray
    layers: np.ndarray
    coat: np.ndarray
    phase: np.ndarray
    flags: np.ndarray
    scatter_at: np.ndarray = np.zeros(0, np.int64)


# ------------------------------------------------------------------------------------------ specs


def bounds(lo: float, hi: float, lo_open: bool = False, hi_open: bool = False, doc: str = "",
           value: str = "number", column: int | None = None, mcolumn: int | None = None) -> dict:
    """Field metadata: the closed (or open) interval a number must lie in, and what it means.

    value: ``"number"``; ``"spectral"`` (a number or a table over λ, `spectra.spectral_value`); ``"ior"``
    (a number, Sellmeier or a table, `spectra.ior_value`). column / mcolumn: the surface / medium row
    column a spectral value feeds (its table goes beside it, see `MaterialArrays`).
    """
    return {"lo": lo, "hi": hi, "lo_open": lo_open, "hi_open": hi_open, "doc": doc, "value": value,
            "column": column, "mcolumn": mcolumn}


def optional(parse, doc: str) -> dict:
    """Field metadata of an optional object field (default None): `parse(value, name, where)` validates it."""
    return {"parse": parse, "doc": doc}


def spec_fields(spec_cls) -> list[dataclasses.Field]:
    """The body fields of a spec class (its dataclass fields), in declaration order."""
    return list(dataclasses.fields(spec_cls))


def _number(v, name: str, meta: Mapping, where: str) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise MaterialError(f"{where}: {name!r} must be a finite number, got {v!r}")
    v = float(v)
    lo, hi, lo_open, hi_open = meta["lo"], meta["hi"], meta["lo_open"], meta["hi_open"]
    if v < lo or v > hi or (lo_open and v == lo) or (hi_open and v == hi):
        raise MaterialError(f"{where}: {name!r} must be in {'(' if lo_open else '['}{lo:g}, {hi:g}"
                            f"{')' if hi_open else ']'}, got {v:g}")
    return v


def _value(v, name: str, meta: Mapping, where: str):
    """One body field, validated by the rule its metadata names."""
    try:
        if "parse" in meta:
            return None if v is None else meta["parse"](v, name, where)
        if meta["value"] == "spectral":
            return spectra.spectral_value(v, name, where, meta["lo"], meta["hi"])
        if meta["value"] == "ior":
            return spectra.ior_value(v, name, where, meta["lo"], meta["hi"])
    except spectra.SpectrumError as exc:
        raise MaterialError(str(exc)) from None
    return _number(v, name, meta, where)


def spec_from_body(spec_cls, name: str, body: dict, where: str, what: str = "material"):
    """Validate a wire body against a kind's spec class and build the spec.

    Unknown fields, missing required fields and numbers out of their `bounds` raise `MaterialError`
    naming the field (and the kind, "for a 'dielectric' material", `what` the family's noun); ``id`` and ``name``
    are allowed and ignored (the service keeps them).
    """
    fields = spec_fields(spec_cls)
    known = {f.name for f in fields}
    extra = set(body) - known - {"type", "id", "name"}
    if extra:
        raise MaterialError(f"{where}: unknown field(s) {sorted(extra)} for a {name!r} {what}")
    required = {f.name for f in fields if f.default is dataclasses.MISSING}
    missing = required - set(body)
    if missing:
        raise MaterialError(f"{where}: missing field(s) {sorted(missing)} for a {name!r} {what}")
    values = {f.name: _value(body[f.name], f.name, f.metadata, where) for f in fields if f.name in body}
    spec = spec_cls(**values)
    problem = spec.check() if hasattr(spec, "check") else None
    if problem:
        raise MaterialError(f"{where}: {problem}")
    return spec


# ----------------------------------------------------------------------------------------- kernels


@njit(cache=True)
def reflect(dx, dy, dz, nx, ny, nz):
    """Mirror direction of d about the plane with unit normal n (either orientation)."""
    c = 2.0 * (dx * nx + dy * ny + dz * nz)
    return dx - c * nx, dy - c * ny, dz - c * nz


@njit(cache=True, error_model="numpy", _nrt=False)
def arrival_normal(ngx, ngy, ngz, dx, dy, dz):
    """The geometric normal turned to the side the ray arrives from."""
    if dx * ngx + dy * ngy + dz * ngz > 0.0:
        return -ngx, -ngy, -ngz
    return ngx, ngy, ngz


@njit(cache=True, error_model="numpy", _nrt=False)
def specular_normal(sa, inst, prim, hu, hv, fx, fy, fz):
    """Shading normal turned to the arrival side `f` (unit); the geometric one where they disagree."""
    sx, sy, sz = shading_normal(sa, inst, prim, hu, hv)
    if sx * fx + sy * fy + sz * fz < 0.0:
        sx, sy, sz = -sx, -sy, -sz
    if not (sx * fx + sy * fy + sz * fz > 0.0):
        return fx, fy, fz
    return sx, sy, sz


@njit(cache=True, error_model="numpy", _nrt=False)
def reflect_specular(sa, inst, prim, hu, hv, dx, dy, dz, fx, fy, fz):
    """Specular reflection about the shading normal; about the geometric one if that would go below the surface."""
    nx, ny, nz = specular_normal(sa, inst, prim, hu, hv, fx, fy, fz)
    rx, ry, rz = reflect(dx, dy, dz, nx, ny, nz)
    if rx * fx + ry * fy + rz * fz <= 0.0:
        rx, ry, rz = reflect(dx, dy, dz, fx, fy, fz)
    inv = 1.0 / math.sqrt(rx * rx + ry * ry + rz * rz)
    return rx * inv, ry * inv, rz * inv


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def param(M, inst, col, lam):
    """Column `col` of the surface row of `inst` at wavelength `lam` nm (0: a white photon, the row's value).

    Inlined: a call would pass the whole material tuple (nine arrays) per bounce."""
    if lam > 0.0 and M.ptab[inst, col] >= 0:   # a white photon never reads the table index
        return spectra.grid_value(M.tables[M.ptab[inst, col]], lam)
    return M.par[inst, col]


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def mparam(M, mi, col, lam):
    """Column `col` of the medium row of solid `mi` at wavelength `lam` nm (0: the row's value)."""
    if lam > 0.0 and M.mtab[mi, col] >= 0:
        return spectra.grid_value(M.tables[M.mtab[mi, col]], lam)
    return M.mpar[mi, col]
