"""``measured_brdf``: an isotropic BRDF tabulated as a goniophotometer measures it, reflecting on both sides.

| field | type | unit | range | default |
| --- | --- | --- | --- | --- |
| table | object or text (below): the BRDF over incidence angle and outgoing bins | sr⁻¹ | ≥ 0, albedo ≤ 1 | or file |
| file | an uploaded table file's id (``POST /optical-files?format=brdf``), text format below | — | 64 hex | or table |

The table, inline (``"table": {...}``) or as the text of a file (``"table": "<file text>"``, format below):

- ``theta_i_deg``: the incidence angles θi measured, strictly increasing in [0, 90) (n_i ≥ 1);
- ``theta_o_deg``: the outgoing polar bin edges, strictly increasing from 0 to 90 (n_o + 1 edges);
- ``dphi_deg``: the azimuth-difference bin edges, strictly increasing from 0 to 180 (n_p + 1 edges). Δφ is the
  outgoing azimuth measured from the plane of incidence on the light's side: 0 is back towards the source, 180 the
  specular (forward) side; the BRDF is isotropic and symmetric about the plane of incidence, so a bin [a, b) also
  covers [−b, −a);
- ``brdf``: [n_i][n_o][n_p] values f(θi; θo bin, Δφ bin) in sr⁻¹, finite and ≥ 0.

The directional albedo of each row, a(θi) = Σ f · 2Δφ_w · (cos²θa − cos²θb) / 2 (the cell's projected solid angle,
both signs of Δφ), must be ≤ 1 (energy); ρ/π everywhere gives a(θi) = ρ, the Lambertian surface.

Text format (``.brdf.txt``; '#' starts a comment, blank lines are ignored)::

    theta_i_deg 0 30 60
    theta_o_deg 0 30 60 90
    dphi_deg 0 90 180
    # then n_i × n_o lines of n_p values: θi rows in order, each its θo bins in order
    0.2 0.2
    ...

Transport: at incidence θi (against the shading normal; clamped to the table's first and last θi) the BRDF is the
linear interpolation of its two neighbouring rows j, j + 1 (weights 1 − t, t). A photon survives with probability
A = (1 − t) a_j + t a_{j+1} (the interpolated albedo), takes row j + 1 with probability t a_{j+1} / A (else row j),
picks a cell from that row's cumulative sums of f × projected solid angle, a sign of Δφ with even odds, and a
direction in the cell distributed as cosθo dω (cos²θo uniform between the edges', Δφ uniform): the density of the
outgoing direction is then f_interp(θi, ωo) cosθo / A exactly, so every estimate is unbiased for the table (no
interpolation between cells: the table is piecewise constant in (θo, Δφ)). The table is unpolarized: a photon is
depolarized.

Effects: `specular` (it is not diffuse). Backward estimator: no.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from tracer.jit import njit
from tracer.optics.frames import onb
from tracer.optics.polarization import depolarize
from tracer.optics.spectra import GRID_N
from tracer.optics.surfaces import zemax_bsdf
from tracer.optics.surfaces.base import (
    ABSORBED,
    CONTINUES,
    GLOSSY,
    MaterialError,
    arrival_normal,
    optional,
    specular_normal,
)
from tracer.rng import uniform

NAME = "measured_brdf"
FLAGS = GLOSSY
MAX_VALUES = 500_000      # brdf values in one table
ALBEDO_TOL = 1e-9


@dataclass(frozen=True)
class Table:
    """A validated table: angles in degrees, brdf flattened [n_i][n_o][n_p] (tuples, so the spec hashes)."""

    theta_i_deg: tuple[float, ...]
    theta_o_deg: tuple[float, ...]
    dphi_deg: tuple[float, ...]
    brdf: tuple[float, ...]

    @property
    def shape(self) -> tuple[int, int, int]:
        return len(self.theta_i_deg), len(self.theta_o_deg) - 1, len(self.dphi_deg) - 1

    def values(self) -> np.ndarray:
        return np.array(self.brdf).reshape(self.shape)

    def cell_weights(self) -> np.ndarray:
        """(n_o, n_p) projected solid angle of each cell, both signs of Δφ: 2Δφ_w (cos²θa − cos²θb) / 2."""
        mu = np.cos(np.radians(self.theta_o_deg))
        mu[-1] = 0.0
        w_phi = np.diff(np.radians(self.dphi_deg))
        return np.outer(mu[:-1] ** 2 - mu[1:] ** 2, w_phi)

    def albedo(self) -> np.ndarray:
        """(n_i,) directional albedo of each θi row."""
        return (self.values() * self.cell_weights()).sum(axis=(1, 2))


def _angles(v, name: str, where: str, first: float | None, last: float | None, below: float | None = None) -> tuple:
    if not isinstance(v, list | tuple) or not v:
        raise MaterialError(f"{where}: {name!r} must be a non-empty list of angles in degrees")
    out = []
    for x in v:
        if isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(x):
            raise MaterialError(f"{where}: {name!r} must hold finite numbers, got {x!r}")
        out.append(float(x))
    if any(b <= a for a, b in zip(out, out[1:], strict=False)):
        raise MaterialError(f"{where}: {name!r} must be strictly increasing, got {out}")
    if first is not None and (out[0] != first or out[-1] != last or len(out) < 2):
        raise MaterialError(f"{where}: {name!r} are bin edges from {first:g} to {last:g} (at least 2), got {out}")
    if below is not None and (out[0] < 0.0 or out[-1] >= below):
        raise MaterialError(f"{where}: {name!r} must lie in [0, {below:g}), got {out}")
    return tuple(out)


def parse_text(text: str, where: str = "table") -> dict:
    """The inline table (a dict) of the text format in the module docstring."""
    heads: dict[str, list[float]] = {}
    rows: list[list[float]] = []
    for k, line in enumerate(text.splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        words = line.split()
        try:
            if words[0] in ("theta_i_deg", "theta_o_deg", "dphi_deg"):
                heads[words[0]] = [float(w) for w in words[1:]]
            else:
                rows.append([float(w) for w in words])
        except ValueError:
            raise MaterialError(f"{where}: line {k} is not numbers: {line[:60]!r}") from None
    for h in ("theta_i_deg", "theta_o_deg", "dphi_deg"):
        if h not in heads:
            raise MaterialError(f"{where}: the text has no {h!r} line")
    n_i, n_o, n_p = len(heads["theta_i_deg"]), len(heads["theta_o_deg"]) - 1, len(heads["dphi_deg"]) - 1
    if len(rows) != n_i * n_o or any(len(r) != n_p for r in rows):
        raise MaterialError(f"{where}: 'brdf' needs {n_i} × {n_o} lines of {n_p} values after the headers, got "
                            f"{len(rows)} lines of {sorted({len(r) for r in rows})} values")
    return {**heads, "brdf": [rows[i * n_o:(i + 1) * n_o] for i in range(n_i)]}


def load(path) -> dict:
    """A material body from a file in the text format: ``{"type": "measured_brdf", "table": <its text>}``."""
    with open(path, encoding="utf-8") as f:
        return {"type": NAME, "table": f.read()}


def parse_table(v, name: str, where: str) -> Table:
    """Validate a table (inline dict or text): shapes, angles, finite non-negative values, albedo ≤ 1 per θi."""
    at = f"{where}: {name}"
    if isinstance(v, str):
        v = zemax_bsdf.parse(v, at) if zemax_bsdf.is_zemax(v) else parse_text(v, at)
    if not isinstance(v, dict):
        raise MaterialError(f"{where}: {name!r} must be an object (theta_i_deg, theta_o_deg, dphi_deg, brdf) or "
                            f"the text of a table file, got {type(v).__name__}")
    extra = set(v) - {"theta_i_deg", "theta_o_deg", "dphi_deg", "brdf"}
    if extra:
        raise MaterialError(f"{where}: unknown field(s) {sorted(extra)} in {name!r}")
    for k in ("theta_i_deg", "theta_o_deg", "dphi_deg", "brdf"):
        if k not in v:
            raise MaterialError(f"{where}: missing '{name}.{k}'")
    ti = _angles(v["theta_i_deg"], f"{name}.theta_i_deg", where, None, None, below=90.0)
    to = _angles(v["theta_o_deg"], f"{name}.theta_o_deg", where, 0.0, 90.0)
    dp = _angles(v["dphi_deg"], f"{name}.dphi_deg", where, 0.0, 180.0)
    shape = (len(ti), len(to) - 1, len(dp) - 1)
    if shape[0] * shape[1] * shape[2] > MAX_VALUES:
        raise MaterialError(f"{where}: '{name}.brdf' has {shape[0] * shape[1] * shape[2]} values, at most "
                            f"{MAX_VALUES}")
    try:
        f = np.array(v["brdf"], dtype=np.float64)
    except (TypeError, ValueError):
        raise MaterialError(f"{where}: '{name}.brdf' must be a [{shape[0]}][{shape[1]}][{shape[2]}] array of "
                            f"numbers") from None
    if f.shape != shape:
        raise MaterialError(f"{where}: '{name}.brdf' must have shape [n_i][n_o][n_p] = {list(shape)}, got "
                            f"{list(f.shape)}")
    if not np.all(np.isfinite(f)) or np.any(f < 0.0):
        raise MaterialError(f"{where}: '{name}.brdf' must be finite and ≥ 0 (sr⁻¹)")
    table = Table(ti, to, dp, tuple(f.ravel().tolist()))
    a = table.albedo()
    j = int(np.argmax(a))
    if a[j] > 1.0 + ALBEDO_TOL:
        raise MaterialError(f"{where}: '{name}.brdf' reflects more than it receives: its directional albedo at "
                            f"theta_i = {ti[j]:g}° is {a[j]:.6g} > 1")
    return table


def parse_file(v, name: str, where: str) -> Table:
    """The table of an uploaded file (its id, `tracer.optics.files`), in the text format; read once while cached."""
    from tracer.optics import files

    try:
        path = files.path_of(v, where, name)
    except files.OpticalFileError as exc:
        raise MaterialError(str(exc)) from None
    return files.cached(v, NAME, lambda: parse_table(path.read_text(encoding="utf-8", errors="replace"), name,
                                                      where))


@dataclass(frozen=True)
class Spec:
    """A measured, isotropic BRDF table."""

    table: Table | None = field(default=None, metadata=optional(
        parse_table, "the BRDF table (inline object or file text), sr⁻¹; or `file`"))
    file: Table | None = field(default=None, metadata=optional(
        parse_file, "an uploaded table file's id (POST /optical-files?format=brdf: 64 hex digits); or `table`"))

    def check(self) -> str | None:
        if (self.table is None) == (self.file is None):
            return "give the BRDF as 'table' (inline) or as 'file' (an uploaded file's id), exactly one"
        return None

    @property
    def measured(self) -> Table:
        """The table, inline or from its file."""
        t = self.table if self.table is not None else self.file
        assert t is not None
        return t


def block(spec: Spec) -> np.ndarray:
    """The kernel's flat data: [cos θi (n_i), cos² of θo edges (n_o + 1), Δφ edges rad (n_p + 1), albedo (n_i),
    running sums of each row's f × projected solid angle over its n_o·n_p cells, normalised to 1 (n_i · n_o · n_p)]."""
    t = spec.measured
    n_i, n_o, n_p = t.shape
    mu = np.cos(np.radians(t.theta_o_deg))
    mu[-1] = 0.0
    p = (t.values() * t.cell_weights()).reshape(n_i, n_o * n_p)
    a = p.sum(axis=1)
    cdf = np.cumsum(p, axis=1) / np.where(a > 0.0, a, 1.0)[:, None]
    cdf[:, -1] = 1.0
    return np.concatenate([np.cos(np.radians(t.theta_i_deg)), mu * mu, np.radians(t.dphi_deg), a, cdf.ravel()])


def row(spec: Spec) -> np.ndarray:
    """[first row of the block in `MaterialArrays.tables` (set by `dispatch`), n_i, n_o, n_p]."""
    n_i, n_o, n_p = spec.measured.shape
    return np.array([0.0, n_i, n_o, n_p])


def effects(spec: Spec) -> tuple[str, ...]:
    return ("specular",)


def diffuse_only(spec: Spec) -> bool:
    return False


def surface_block(spec: Spec) -> tuple[int, np.ndarray]:
    """(the row column that takes the block's first table row, the block) for `dispatch.pack_materials`."""
    return 0, block(spec)


# ----------------------------------------------------------------------------------------- kernel


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def tab(M, n):
    """Element n of the flattened `M.tables`."""
    return M.tables[n // GRID_N, n - (n // GRID_N) * GRID_N]


@njit(cache=True, error_model="numpy", _nrt=False)
def scatter(sa, M, inst, prim, hu, hv, dx, dy, dz, ngx, ngy, ngz, med, depth, key, dim, lam, pol):
    fx, fy, fz = arrival_normal(ngx, ngy, ngz, dx, dy, dz)
    nx, ny, nz = specular_normal(sa, inst, prim, hu, hv, fx, fy, fz)
    base = int(M.par[inst, 0]) * GRID_N
    n_i, n_o, n_p = int(M.par[inst, 1]), int(M.par[inst, 2]), int(M.par[inst, 3])
    o_mu2, o_phi, o_a = base + n_i, base + n_i + n_o + 1, base + n_i + n_o + n_p + 2
    o_cdf = o_a + n_i
    nc = n_o * n_p
    ci = min(max(-(dx * nx + dy * ny + dz * nz), 0.0), 1.0)
    # the bracketing rows (cos θi decreases along the table)
    j, t = 0, 0.0
    if n_i > 1:
        if ci >= tab(M, base):
            j, t = 0, 0.0
        elif ci <= tab(M, base + n_i - 1):
            j, t = n_i - 2, 1.0
        else:
            j = 0
            while j < n_i - 2 and tab(M, base + j + 1) > ci:
                j += 1
            th0, th1 = math.acos(tab(M, base + j)), math.acos(tab(M, base + j + 1))
            t = (math.acos(ci) - th0) / (th1 - th0)
    a0 = tab(M, o_a + j)
    a1 = tab(M, o_a + j + 1) if n_i > 1 else 0.0
    pa0, pa1 = (1.0 - t) * a0, t * a1
    u = uniform(key, dim)
    if u >= pa0 + pa1:
        return ABSORBED, dx, dy, dz, 0.0, depth, dim + 5
    r = j if u < pa0 else j + 1
    # the cell: first running sum above u2 (binary search)
    u2 = uniform(key, dim + 1)
    lo, hi = 0, nc - 1
    c0 = o_cdf + r * nc
    while lo < hi:
        mid = (lo + hi) // 2
        if tab(M, c0 + mid) > u2:
            hi = mid
        else:
            lo = mid + 1
    io = lo // n_p
    ip = lo - io * n_p
    m2a, m2b = tab(M, o_mu2 + io), tab(M, o_mu2 + io + 1)
    mu = math.sqrt(max(0.0, m2a + uniform(key, dim + 2) * (m2b - m2a)))
    pa, pb = tab(M, o_phi + ip), tab(M, o_phi + ip + 1)
    ph = pa + uniform(key, dim + 3) * (pb - pa)
    if uniform(key, dim + 4) < 0.5:
        ph = -ph
    # frame: t along the incident direction's projection (towards the source), b = n × t
    wx, wy, wz = -dx, -dy, -dz
    tx, ty, tz = wx - ci * nx, wy - ci * ny, wz - ci * nz
    ln = math.sqrt(tx * tx + ty * ty + tz * tz)
    if ln > 1e-9:
        tx, ty, tz = tx / ln, ty / ln, tz / ln
    else:
        (tx, ty, tz), _ = onb(nx, ny, nz)
    bx, by, bz = ny * tz - nz * ty, nz * tx - nx * tz, nx * ty - ny * tx
    st = math.sqrt(max(0.0, 1.0 - mu * mu))
    cp, sp = st * math.cos(ph), st * math.sin(ph)
    ox, oy, oz = cp * tx + sp * bx + mu * nx, cp * ty + sp * by + mu * ny, cp * tz + sp * bz + mu * nz
    inv = 1.0 / math.sqrt(ox * ox + oy * oy + oz * oz)
    ox, oy, oz = ox * inv, oy * inv, oz * inv
    if ox * fx + oy * fy + oz * fz <= 0.0:   # below the geometric surface (a shading normal far from it)
        return ABSORBED, dx, dy, dz, 0.0, depth, dim + 5
    depolarize(pol)
    return CONTINUES, ox, oy, oz, 1.0, depth, dim + 5
