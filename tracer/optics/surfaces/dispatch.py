"""The registration of surface kinds and thin elements: kind id = position in `KINDS`, and the one switch
on a surface kind (`scatter`, `albedo`). Adding a kind: its module and one entry in `KINDS` (and a branch in
`albedo` if the backward estimator may follow it).

`scatter` is inlined into the transport kernels (``inline="always"``, which `tracer.jit` makes LLVM's
forceinline), and so is the Lambertian kind's: a real call per bounce passes the scene's and the materials'
tuples, a few hundred words, and made the diffuse room 1.25x slower than the switch written inline. Every other
kind is called through its address in `MaterialArrays.scatter_at` (`scatter_by_address`, `tracer.jit.kind_table`):
compiled once on its own and cached on its own, it is no part of any kernel, so a new kind adds no compile time to
the forward, backward or luminance kernels (on a CUDA device the same call is a branch chain compiled in).
`bind` fills the table for this process; `tracer.backends.run_kernel` does it before every CPU run.

Python side: `material_spec` turns a wire body (or a spec) into the kind's typed spec (an older body is read
through its kind's `upgrade`, `upgrade_body`), `pack_materials` builds the kernels' `MaterialArrays` for every
instance id (a solid's medium packed by `tracer.optics.media.dispatch`), `effects_of` and `backward_ok` answer from
the specs what the scene calls for.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numba
import numpy as np
from numba import types

from tracer.elements import diffraction
from tracer.elements import features as fx
from tracer.jit import kind_table, njit
from tracer.kinds import relief
from tracer.optics import mie, spectra
from tracer.optics.coating import Coating
from tracer.optics.elements import diffuser, polarizer, retarder
from tracer.optics.media.dispatch import pack_medium
from tracer.optics.polarization import depolarize
from tracer.optics.surfaces import (
    black,
    dielectric,
    lambertian,
    measured_brdf,
    microfacet,
    mirror,
    mix,
)
from tracer.optics.surfaces.base import (
    ABSORBED,
    CONTINUES,
    MIE_ROW,
    N_MPAR,
    N_PAR,
    NO_MEDIUM,
    NONE,
    STACK_FULL,
    MaterialArrays,
    MaterialError,
    spec_from_body,
)
from tracer.rng import uniform

KINDS = (black, lambertian, mirror, mix, dielectric, diffuser, polarizer, retarder, microfacet, measured_brdf)
(BLACK, LAMBERTIAN, MIRROR, MIX, DIELECTRIC, DIFFUSER, POLARIZER, RETARDER, MICROFACET,
 MEASURED_BRDF) = range(len(KINDS))
KIND_OF = {m.NAME: k for k, m in enumerate(KINDS)}
#: the older wire types a kind reads (its ``ALIASES``, rewritten by its ``upgrade``)
ALIAS_OF = {a: k for k, m in enumerate(KINDS) for a in getattr(m, "ALIASES", ())}
#: the lobes (`base`: DIFFUSE, GLOSSY, SPECULAR, TRANSMITS; 0 absorbs) of an element feature's own surface
#: (`fx.MAT_BLACK`, `fx.MAT_LAMBERTIAN`); an instance's are `MaterialArrays.flags`: what the transport asks instead
#: of a kind
FEATURE_FLAGS = np.zeros(max(fx.MAT_BLACK, fx.MAT_LAMBERTIAN) + 1, np.int64)
FEATURE_FLAGS[fx.MAT_BLACK], FEATURE_FLAGS[fx.MAT_LAMBERTIAN] = black.FLAGS, lambertian.FLAGS
_MODULE_OF_SPEC = {m.Spec: m for m in KINDS}


def module_of(spec):
    """The kind module of a typed spec."""
    try:
        return _MODULE_OF_SPEC[type(spec)]
    except KeyError:
        raise MaterialError(f"not a material spec: {type(spec).__name__}") from None


def upgrade_body(body: Any, where: str = "material") -> Any:
    """A material body in today's form: an older one (a folded kind's type, fields since moved) rewritten by its
    kind's ``upgrade``; anything else returned as it is (validation says what is wrong with it)."""
    t = body.get("type") if isinstance(body, dict) else None
    if not isinstance(t, str):   # not a body, or no type a kind could have: validation says what is wrong
        return body
    k = KIND_OF.get(t, ALIAS_OF.get(t))
    if k is None or not hasattr(KINDS[k], "upgrade"):
        return body
    try:
        return KINDS[k].upgrade(body)
    except MaterialError as exc:
        raise MaterialError(f"{where}: {exc}") from None


def material_spec(body, where: str = "material"):
    """The typed spec of a material: a spec is returned as it is, a wire body (dict) is validated (an older one
    read through `upgrade_body`).

    Raises
    ------
    MaterialError
        Not a dict or spec, unknown type, unknown or missing field, value out of range (naming it).
    """
    if type(body) in _MODULE_OF_SPEC:
        return body
    if not isinstance(body, dict):
        raise MaterialError(f"{where}: expected a material body (dict), got {type(body).__name__}")
    body = upgrade_body(body, where)
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


def flags_of(spec) -> int:
    """The lobes of a material's surface (`base`: the kind's ``flags(spec)`` where its fields decide, else its
    ``FLAGS``)."""
    m = module_of(spec)
    return m.flags(spec) if hasattr(m, "flags") else m.FLAGS


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
    flags = np.zeros(n, np.int64)
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
        kind[i], par[i], medium[i], mpar[i], ptab[i], mtab[i], coat[i], flags[i] = rows[spec]
    return MaterialArrays(kind, par, medium, mpar, ptab, mtab, tables.array(), tables.layer_array(), coat,
                          tables.phase_array(), flags, np.zeros(len(KINDS), np.int64))


class _Tables:
    """The spectral tables and coating layers of a material table while it is packed (shared, deduplicated)."""

    def __init__(self):
        self.rows: dict[bytes, int] = {}
        self.values: list[np.ndarray] = []
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
        if key not in self.rows:
            self.rows[key] = len(self.values)
            self.values.append(np.asarray(values, np.float64))
        return self.rows[key]

    def add_block(self, flat: np.ndarray) -> int:
        """Append a kind's flat data (a measured table) as whole rows, contiguous and not shared; the first row."""
        first = len(self.values)
        n = -(-len(flat) // spectra.GRID_N)
        padded = np.zeros(n * spectra.GRID_N)
        padded[:len(flat)] = flat
        self.values.extend(padded.reshape(n, spectra.GRID_N))
        return first

    def array(self) -> np.ndarray:
        if not self.values:
            return np.zeros((1, spectra.GRID_N))
        return np.stack(self.values)

    def layer_array(self) -> np.ndarray:
        return np.array(self.layers, np.float64).reshape(-1, 2) if self.layers else np.zeros((1, 2))


def _rows(spec, tables: _Tables):
    """(kind id, par, medium kind, mpar, ptab, mtab, coat, flags) of one spec."""
    m = module_of(spec)
    par = _row(m, spec)
    ptab = np.full(N_PAR, -1, np.int32)
    coat = np.zeros(2, np.int32)
    for f in dataclasses.fields(spec):
        v = getattr(spec, f.name)
        if spectra.varies(v) and f.metadata.get("column") is not None:
            ptab[f.metadata["column"]] = tables.add(v.grid())
        elif isinstance(v, Coating):
            coat[:] = len(tables.layers), len(v.layers)
            tables.layers.extend(v.layers)
    if hasattr(m, "surface_block"):   # a kind's own flat data (a measured table), rows of `tables` from par[col]
        col, flat = m.surface_block(spec)
        par[col] = tables.add_block(flat)
    medium, host_ior = m.inside(spec) if hasattr(m, "inside") else (None, 1.0)
    mkind, mpar, mtab = pack_medium(medium, host_ior, tables)
    return KIND_OF[m.NAME], par, mkind, mpar, ptab, mtab, coat, flags_of(spec)


# ----------------------------------------------------------------------------------------- the switch



def _scatter_signature(head):
    """The argument types every kind's `scatter` is compiled for (`base` has the contract), from those of the
    scene's and the materials' tuples (`head`)."""
    i8, u8, f8 = types.int64, types.uint64, types.float64
    return (head[0], head[1], i8, i8, *[f8] * 8, types.int64[::1], i8, u8, i8, f8, types.float64[::1])


#: what every kind's `scatter` returns: (status, dx, dy, dz, f, depth, dim), `base` has the contract
SCATTER_RETURNS = types.Tuple((types.int64, *[types.float64] * 4, types.int64, types.int64))
#: the entry of `MaterialArrays.scatter_at` past the kinds: an element used through a table (`element_table_scatter`)
ELEMENT_TABLE = len(KINDS)
_TABLES: dict = {}


def bind(sa, M):
    """`M` with its table of `scatter` addresses (`MaterialArrays.scatter_at`) for the types of `sa` and `M`, holding
    (at least) the kinds `M` holds: what a kernel on this process's CPU needs before it runs
    (`tracer.backends.run_kernel`). A kind no scene of this process has held is never compiled."""
    head = (numba.typeof(sa), numba.typeof(M))
    table = _TABLES.setdefault(head, np.zeros(scatter_by_address.size, np.int64))
    kinds = np.unique(M.kind)
    if len(sa.el_i) and (sa.el_i[:, fx.MODEL] != fx.EXACT).any():   # a tabulated BSDF or a grating's orders
        kinds = np.append(kinds, ELEMENT_TABLE)
    scatter_by_address.bind(table, head, kinds)
    return M._replace(scatter_at=table)


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def feature_surface(sa, inst, prim):
    """``(kind, reflectance)`` of a hit on an element's feature that has a surface of its own (`fx.MAT_BLACK`,
    `fx.MAT_LAMBERTIAN`: a printed dot); ``(fx.MAT_PART, 0)`` where the hit takes the instance's material."""
    if prim < -1 and sa.inst_aux[inst] >= 0:
        r, _ = relief.feature_row(sa, inst, prim)
        k = int(sa.el_f[r, fx.FMAT])
        if k >= 0:
            return k, sa.el_f[r, fx.FRHO]
    return fx.MAT_PART, 0.0


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def surface_flags(sa, M, inst, prim):
    """The lobes (`base`) of the surface a hit meets: an element feature's own, else the instance's material's."""
    own, _ = feature_surface(sa, inst, prim)
    if own != fx.MAT_PART:
        return FEATURE_FLAGS[own]
    return M.flags[inst]


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def table_row(sa, inst, prim):
    """The element row of a hit on the support of an element used through a table (its tabulated BSDF, `fx.BSDF`,
    or a grating's orders, `fx.GRATING`), -1 for any other hit."""
    if prim < 0 or inst >= sa.inst_aux.shape[0] or sa.inst_aux[inst] < 0:
        return -1
    r, _ = relief.part_row(sa, inst, prim)
    if r < 0 or sa.el_i[r, fx.MODEL] == fx.EXACT:
        return -1
    return r


@njit(cache=True, error_model="numpy", inline="always")
def mu_bin(mu, n_mu, split, muc):
    """The |cos θ| bin of `mu` on a tabulated BSDF's side (`tracer.elements.bsdf.mu_edges`): `n_mu` uniform bins
    (`split` 0), or `split` uniform bins below the critical angle's |cos| `muc` and the rest above it."""
    if split == 0:
        return min(int(mu * n_mu), n_mu - 1)
    if mu < muc:
        return min(int(mu / muc * split), split - 1)
    return min(split + int((mu - muc) / (1.0 - muc) * (n_mu - split)), n_mu - 1)


@njit(cache=True, error_model="numpy", inline="always")
def mu_in_bin(j, u, n_mu, split, muc):
    """The |cos θ| at fraction `u` of bin `j`'s width (`mu_bin`'s bins)."""
    if split == 0:
        return (j + u) / n_mu
    if j < split:
        return (j + u) / split * muc
    return muc + (j - split + u) / (n_mu - split) * (1.0 - muc)


@njit(cache=True, error_model="numpy", _nrt=False)
def table_level(sa, r, inst, prim, hu, hv, u):
    """Which of a density map's tables (`tracer.elements.bsdf`: levels evenly spaced in fill from 0 to 1) scatters
    a photon meeting the support of element row `r` at ``(prim, hu, hv)`` (its triangle of the part and barycentrics):
    the map's fill f where it lands (0 off the map) gives the levels k and k + 1 around it; k + 1 with probability
    f (K − 1) − k, drawn with the uniform number `u`."""
    F = sa.el_f[r]
    I = sa.el_i[r]
    px, py, pz = relief.point(sa, inst, prim, hu, hv)
    qx, qy, qz = px - F[fx.O_X], py - F[fx.O_X + 1], pz - F[fx.O_X + 2]
    pu = F[fx.MM] * (qx * F[fx.U_X] + qy * F[fx.U_X + 1] + qz * F[fx.U_X + 2])
    pv = F[fx.MM] * (qx * F[fx.V_X] + qy * F[fx.V_X + 1] + qz * F[fx.V_X + 2])
    iu = int(math.floor((pu - F[fx.FILL_U0]) / F[fx.FILL_DU]))   # int(): a device's floor is a float
    iv = int(math.floor((pv - F[fx.FILL_V0]) / F[fx.FILL_DV]))
    fill = 0.0
    if 0 <= iu < I[fx.FILL_NU] and 0 <= iv < I[fx.FILL_NV]:
        j = I[fx.FILL] + iv * I[fx.FILL_NU] + iu
        width = sa.el_tab.shape[1]
        fill = sa.el_tab[j // width, j - (j // width) * width]
    x = min(max(fill, 0.0), 1.0) * (I[fx.LEVELS] - 1)
    k = min(int(x), I[fx.LEVELS] - 1)
    if k < I[fx.LEVELS] - 1 and u < x - k:
        k += 1
    return k


@njit(cache=True, error_model="numpy", _nrt=False)
def bsdf_scatter(sa, r, inst, dx, dy, dz, med, depth, key, dim, pol, level):
    """Scatter a photon arriving along d on the support of element row `r` by its table (`tracer.elements.bsdf`:
    the arriving bin is the reversed direction's, in the support's frame; the leaving bin is drawn from the row's
    running sums, the direction uniform over its solid angle); `level`: which of a density map's tables
    (`table_level`; 0 for a periodic layout's one). Crossing the face pushes or pops the part's medium; the table is
    unpolarized, so the photon is depolarized."""
    F = sa.el_f[r]
    du, dv, dn, norm = diffraction.in_support(sa, r, inst, dx, dy, dz)
    n_mu = sa.el_i[r, fx.TAB_MU]
    n_phi = sa.el_i[r, fx.TAB_PHI]
    split = sa.el_i[r, fx.TAB_SPLIT]
    muc = F[fx.TAB_MUC]
    half = n_mu * n_phi
    side_in = 1 if dn >= 0.0 else 0          # travelling out of the solid: it came from side 1
    im = mu_bin(abs(dn) / norm, n_mu, split if side_in == 1 else 0, muc)
    phi = math.atan2(-dv, -du)
    if phi < 0.0:
        phi += 2.0 * math.pi
    ip = min(int(phi / (2.0 * math.pi) * n_phi), n_phi - 1)
    nb = 2 * half
    row = sa.el_i[r, fx.TAB] + level * nb + side_in * half + im * n_phi + ip
    u = uniform(key, dim)
    if not u < sa.el_tab[row, nb - 1]:
        return ABSORBED, dx, dy, dz, 0.0, depth, dim + 1
    b = 0
    while b < nb - 1 and sa.el_tab[row, b] <= u:
        b += 1
    side_out = b // half
    rest = b - side_out * half
    jm = rest // n_phi
    jp = rest - jm * n_phi
    mu = mu_in_bin(jm, uniform(key, dim + 1), n_mu, split if side_out == 1 else 0, muc)
    ph = (jp + uniform(key, dim + 2)) / n_phi * 2.0 * math.pi
    st = math.sqrt(max(0.0, 1.0 - mu * mu))
    wu = st * math.cos(ph)
    wv = st * math.sin(ph)
    wn = mu if side_out == 0 else -mu
    bx = wu * F[fx.U_X] + wv * F[fx.V_X] + wn * F[fx.N_X]
    by = wu * F[fx.U_X + 1] + wv * F[fx.V_X + 1] + wn * F[fx.N_X + 1]
    bz = wu * F[fx.U_X + 2] + wv * F[fx.V_X + 2] + wn * F[fx.N_X + 2]
    W = sa.world_from_object[inst]
    ox = W[0, 0] * bx + W[0, 1] * by + W[0, 2] * bz
    oy = W[1, 0] * bx + W[1, 1] * by + W[1, 2] * bz
    oz = W[2, 0] * bx + W[2, 1] * by + W[2, 2] * bz
    inv = 1.0 / math.sqrt(ox * ox + oy * oy + oz * oz)
    depolarize(pol)
    if side_in == 0 and side_out == 1:       # into the part: its medium
        if depth == med.shape[0]:
            return STACK_FULL, dx, dy, dz, 0.0, depth, dim + 3
        med[depth] = inst
        depth += 1
    elif side_in == 1 and side_out == 0:     # out of the part
        depth = diffraction.leave_part(med, depth, inst)
    return CONTINUES, ox * inv, oy * inv, oz * inv, 1.0, depth, dim + 3


@njit(cache=True, error_model="numpy", _nrt=False)
def element_table_scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim, lam, pol):
    """What the table of the element on instance `inst` does to a photon meeting its support (a kind's `scatter`
    signature, so that it is called through `scatter_by_address` like one: compiled on its own, only in a process
    whose scenes hold such an element, and in no kernel): a grating's orders (`tracer.elements.diffraction`) or a
    tabulated BSDF (`bsdf_scatter`)."""
    r = table_row(sa, inst, prim)
    if sa.el_i[r, fx.MODEL] == fx.GRATING:
        return diffraction.scatter(sa, r, inst, dx, dy, dz, med, depth, key, dim, lam, pol)
    if sa.el_i[r, fx.LEVELS] > 1:   # a density map's: the table of the fill where the photon lands
        level = table_level(sa, r, inst, prim, hu, hv, uniform(key, dim))
        return bsdf_scatter(sa, r, inst, dx, dy, dz, med, depth, key, dim + 1, pol, level)
    return bsdf_scatter(sa, r, inst, dx, dy, dz, med, depth, key, dim, pol, 0)


#: the kinds past the Lambertian one and the element tables, called through `MaterialArrays.scatter_at`
#: (`tracer.jit.kind_table`)
scatter_by_address = kind_table(
    "scatter_by_address", {**{k: m.scatter for k, m in enumerate(KINDS) if k > LAMBERTIAN},
                           ELEMENT_TABLE: element_table_scatter}, _scatter_signature, SCATTER_RETURNS)


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def surface_albedo(sa, M, inst, prim):
    """`albedo` of the hit: a feature's own reflectance where it has a surface of its own."""
    fk, rho = feature_surface(sa, inst, prim)
    if fk == fx.MAT_LAMBERTIAN:
        return rho
    if fk == fx.MAT_BLACK:
        return 0.0
    return albedo(M, inst)


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim, lam, pol):
    """What the surface of instance `inst` does to a photon of wavelength `lam` nm (0: white) and polarization
    state `pol` (`tracer.optics.polarization`) arriving along d (`base` has the contract); on an element's feature
    with a surface of its own (`feature_surface`), what that surface does; on the support of an element used through
    its tabulated BSDF or a grating's orders (`table_row`), what the table says."""
    if table_row(sa, inst, prim) >= 0:
        return scatter_by_address(M.scatter_at, ELEMENT_TABLE, (sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz,
                                                                med, depth, key, dim, lam, pol))
    fk, frho = feature_surface(sa, inst, prim)
    if fk == fx.MAT_LAMBERTIAN:
        return lambertian.scatter_rho(frho, dx, dy, dz, ngx, ngy, ngz, depth, key, dim, pol)
    if fk == fx.MAT_BLACK:
        return ABSORBED, dx, dy, dz, 0.0, depth, dim
    k = M.kind[inst]
    if k == LAMBERTIAN:
        return lambertian.scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim, lam, pol)
    if k > LAMBERTIAN and k < len(M.scatter_at):
        return scatter_by_address(M.scatter_at, k, (sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth,
                                                     key, dim, lam, pol))
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

