"""An element's tabulated BSDF: how its micro-structured face scatters, computed once from the exact model.

The table is the element's ``bsdf`` model (docs/DESIGN.md "Optical elements with an inside"): for a support of a solid
of index ``ior`` in air, the probability that light arriving from direction bin ``i`` leaves into direction bin ``o``.
Directions are binned on both sides of the support, in its frame (u, v, n: `tracer.elements.support`): side 0 the
air side (w > 0 for the leaving light, arriving light travels down), side 1 the solid's; on each side ``n_mu``
bins uniform in |cos theta| (equal solid angles) by ``n_phi`` in the azimuth from u. Bin index
``side * n_mu * n_phi + i_mu * n_phi + i_phi``; an arriving direction is binned by the way it came *from*: a photon
falling from the air onto the face is in side 0's bin of its reversed direction.

`tabulate` traces, for each arriving bin, ``rays`` photons with directions uniform over the bin and points uniform
over a patch of the element (the middle of a support many features wide, or a density map's or point list's own
extent), through the exact geometry (`tracer.Scene.intersect` on the relief kind) with unpolarized Fresnel
reflection and refraction at every crossing (total internal reflection included) until they leave: upwards past
the features (side 0) or down into the solid (side 1). Each leaving direction is counted in its bin. A row's sum is
the light that leaves (1 for a lossless element); ``cdf`` holds the rows' running sums, what the transport samples.
Its resolution error is the bins' width: a quantity that depends on where in a bin light leaves (a narrow lobe)
differs by up to that; totals and diffuse quantities agree within the Monte Carlo error of the table.

How far off that makes a transmitted flux is measured when the table is made (`model_error`, the table's ``error``):
for probe beams from each arriving bin's azimuth centre at its |cos θ| edges and middle, on both sides, the exact
model is traced and set against the table's row, on the quantity that matters downstream: from the air side, the
share of the beam that crosses the element *and then a plain parallel face of the same solid* (Fresnel, total
internal reflection: the table's direction drawn uniformly over a bin moves light across the critical angle that
the exact model does not); from the solid's side, the share that leaves into the air. The worst probe's deviation
(table − exact, a share of the flux meeting the element) and its standard error are kept with the table and carried
by every answer that uses it (issue 54, item 11: a dotted plate transmitted 2.4 % more through its table).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tracer.elements import features as fx
from tracer.elements.checks import ElementError
from tracer.elements.microstructure import Microstructure

N_MU, N_PHI, RAYS = 6, 8, 4000
MAX_BOUNCES = 64


@dataclass(frozen=True)
class Table:
    """A tabulated BSDF: ``cdf`` (nb, nb) float64 running sums of each arriving bin's row; its bins and index;
    ``error``: how far it is off, measured against the exact model when it was made (`model_error`: per side; None
    for a table kept before it was measured)."""

    ior: float
    n_mu: int
    n_phi: int
    cdf: np.ndarray
    rays: int
    error: dict | None = None

    @property
    def bins(self) -> int:
        return 2 * self.n_mu * self.n_phi

    @property
    def probabilities(self) -> np.ndarray:
        """(nb, nb) the probability of each (arriving, leaving) pair of bins."""
        return np.diff(self.cdf, axis=1, prepend=0.0)

    def arrays(self) -> dict[str, np.ndarray]:
        out = {"cdf": self.cdf, "params": np.array([self.ior, self.n_mu, self.n_phi, self.rays], np.float64)}
        if self.error is not None:
            out["error"] = np.array([[e["deviation"], e["stderr"], SIDES.index(e["side"]), e["theta_deg"],
                                      e["phi_deg"], e["probes"], e["probe_rays"], e["exact"]]
                                     for e in (self.error[side] for side in SIDES)], np.float64)
        return out

    @classmethod
    def from_arrays(cls, arrays) -> Table:
        p = arrays["params"]
        error = None
        if "error" in getattr(arrays, "files", arrays):
            error = {}
            for row in np.asarray(arrays["error"], np.float64):
                e = [float(x) for x in row]
                error[SIDES[int(e[2])]] = _error_dict(e[0], e[1], SIDES[int(e[2])], e[3], e[4], int(e[5]), int(e[6]),
                                                      e[7])
        return cls(float(p[0]), int(p[1]), int(p[2]), np.asarray(arrays["cdf"], np.float64), int(p[3]), error)


SIDES = ("air", "solid")
MEASURES = {"air": "share of a beam from the air that crosses the element and a plain parallel face of the solid",
            "solid": "share of a beam from inside the solid that leaves through the element into the air"}


def _error_dict(dev: float, se: float, side: str, theta: float, phi: float, probes: int, rays: int,
                exact: float) -> dict:
    return {"deviation": dev, "stderr": se, "side": side, "theta_deg": theta, "phi_deg": phi, "probes": probes,
            "probe_rays": rays, "exact": exact, "measure": MEASURES[side]}


def bin_of(w: np.ndarray, n_mu: int, n_phi: int) -> np.ndarray:
    """Bin of leaving directions ``w`` (k, 3) in the support's frame (u, v, n): side 0 where w_n > 0."""
    side = (w[:, 2] <= 0.0).astype(np.int64)
    mu = np.minimum((np.abs(w[:, 2]) * n_mu).astype(np.int64), n_mu - 1)
    phi = np.mod(np.arctan2(w[:, 1], w[:, 0]), 2.0 * math.pi)
    ip = np.minimum((phi / (2.0 * math.pi) * n_phi).astype(np.int64), n_phi - 1)
    return side * n_mu * n_phi + mu * n_phi + ip


def sample_in_bin(b: np.ndarray, n_mu: int, n_phi: int, r1: np.ndarray, r2: np.ndarray) -> np.ndarray:
    """Leaving directions (k, 3) uniform over the solid angle of bins ``b``."""
    side, rest = np.divmod(b, n_mu * n_phi)
    im, ip = np.divmod(rest, n_phi)
    mu = (im + r1) / n_mu
    phi = (ip + r2) / n_phi * 2.0 * math.pi
    s = np.sqrt(np.maximum(0.0, 1.0 - mu * mu))
    return np.column_stack([s * np.cos(phi), s * np.sin(phi), np.where(side == 0, mu, -mu)])


def _fresnel(cos_i: np.ndarray, n1: np.ndarray, n2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unpolarized Fresnel reflectance and cos of the refracted angle (nan under total internal reflection)."""
    eta = n1 / n2
    sin2 = eta * eta * np.maximum(0.0, 1.0 - cos_i * cos_i)
    tir = sin2 >= 1.0
    cos_t = np.sqrt(np.maximum(0.0, 1.0 - sin2))
    rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t)
    rp = (n2 * cos_i - n1 * cos_t) / (n2 * cos_i + n1 * cos_t)
    r = np.where(tir, 1.0, 0.5 * (rs * rs + rp * rp))
    return r, np.where(tir, np.nan, cos_t)


MARGIN_MM = 5.0   # support beyond the patch on every side: a grazing ray starting off the face runs onto the patch
MU_MIN = 0.02     # arriving directions within 1.1 degrees of grazing are taken at 1.1 degrees


def _patch(e: Microstructure) -> tuple[float, float, float, float, float, float]:
    """(u0, v0, su, sv) of the patch rays land on and (lu, lv) of the support, mm (periodic layouts only)."""
    if e.layout not in (fx.GRID, fx.HEX):
        raise ElementError("model: a tabulated BSDF is built for periodic layouts (grid, hex) for now; a density map "
                           "or a point list varies over its face: use the exact model")
    cu, cv = e.cell
    k = max(20, int(math.ceil(0.5 / min(cu, cv))))     # at least 20 cells and 0.5 mm
    u0 = MARGIN_MM - math.fmod(MARGIN_MM, cu)            # a whole number of cells from the support's corner
    v0 = MARGIN_MM - math.fmod(MARGIN_MM, cv)
    return u0, v0, k * cu, k * cv, u0 + k * cu + MARGIN_MM, v0 + k * cv + MARGIN_MM


def _scene(e: Microstructure, lu: float, lv: float, depth: float):
    from tracer.scene import Scene
    from tracer.warmup import box

    s = Scene()
    v, t = box([0.0, 0.0, -depth], [lu, lv, 0.0])
    part = s.add_instance(s.add_geometry(v, t), np.eye(4))
    s.set_element(part, e, facing=[0, 0, 1], mm_per_unit=1.0)
    s.commit()
    return s


def trace(s, ior: float, o: np.ndarray, d: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Leaving directions (k, 3) of photons from points ``o`` along ``d`` through scene `s` (`_scene`: mm, the
    support's frame u, v, n = x, y, z, the face at z = 0 over a solid below), and whether each left (False: still
    inside after MAX_BOUNCES). A photon leaves where it meets nothing (upwards, into the air) or the solid's other
    faces (down into it); at the face and the features it is reflected or refracted (unpolarized Fresnel)."""
    o = o.copy()
    d = d.copy()
    alive = np.ones(len(o), bool)
    done = np.zeros(len(o), bool)
    for _ in range(MAX_BOUNCES):
        idx = np.flatnonzero(alive)
        if len(idx) == 0:
            break
        h = s.intersect(o[idx], d[idx])
        miss = ~np.isfinite(h.t)
        p = o[idx] + np.where(miss, 0.0, h.t)[:, None] * d[idx]
        on_face = (h.primitive < -1) | ((np.abs(p[:, 2]) < 1e-9) & (h.normal[:, 2] > 0.5))
        leave = miss | ~on_face
        alive[idx[leave]] = False
        done[idx[leave]] = True
        k = idx[~leave]
        if len(k) == 0:
            break
        nrm = h.normal[~leave]
        dd = d[k]
        cos = -np.sum(dd * nrm, axis=1)
        entering = cos > 0.0
        n1 = np.where(entering, 1.0, ior)
        n2 = np.where(entering, ior, 1.0)
        r, cos_t = _fresnel(np.abs(cos), n1, n2)
        refl = rng.random(len(k)) < r
        f = np.where(entering[:, None], nrm, -nrm)          # the normal on the arriving side
        out = np.empty_like(dd)
        out[refl] = dd[refl] + 2.0 * np.abs(cos[refl])[:, None] * f[refl]
        t = ~refl
        eta = (n1 / n2)[t]
        out[t] = eta[:, None] * dd[t] + (eta * np.abs(cos[t]) - cos_t[t])[:, None] * f[t]
        out /= np.linalg.norm(out, axis=1, keepdims=True)
        d[k] = out
        o[k] = p[~leave] + np.where(refl, 1e-9, -1e-9)[:, None] * f   # on the side it goes on from
    return d, done


def tabulate(e: Microstructure, ior: float, *, n_mu: int = N_MU, n_phi: int = N_PHI, rays: int | None = None,
             seed: int = 0) -> Table:
    """The element's BSDF on a solid of index `ior` in air, traced through its exact geometry (module docstring);
    `rays` per arriving bin (default `RAYS`, read when called)."""
    rays = RAYS if rays is None else int(rays)
    if isinstance(ior, bool) or not (isinstance(ior, int | float) and math.isfinite(ior) and 1.0 <= ior <= 4.0):
        raise ElementError(f"ior must be a number in [1, 4] for a tabulated BSDF, got {ior!r}")
    rng = np.random.default_rng(seed)
    u0, v0, su, sv, lu, lv = _patch(e)
    s = _scene(e, lu, lv, 10.0 * e.h + 1.0)
    nb = 2 * n_mu * n_phi
    counts = np.zeros((nb, nb))
    b_in = np.repeat(np.arange(nb), rays)
    # an arriving bin is the reversed direction's: side 0 comes from the air (travels down), side 1 from the solid
    w = sample_in_bin(b_in, n_mu, n_phi, rng.random(len(b_in)), rng.random(len(b_in)))
    w[:, 2] = np.copysign(np.maximum(np.abs(w[:, 2]), MU_MIN), w[:, 2])
    d = -w / np.linalg.norm(w, axis=1, keepdims=True)
    top = (e.h if e.sign > 0 else 0.0) + 1e-4
    bottom = -(e.h if e.sign < 0 else 0.0) - 1e-4
    z = np.where(b_in < nb // 2, top, bottom)
    pu = u0 + rng.random(len(b_in)) * su
    pv = v0 + rng.random(len(b_in)) * sv
    # start just off the face, back along d from a point of the patch's plane (it may meet a feature before it)
    o = np.column_stack([pu, pv, np.zeros(len(b_in))]) + (z / d[:, 2])[:, None] * d
    out, left = trace(s, ior, o, d, rng)
    b_out = bin_of(out, n_mu, n_phi)
    np.add.at(counts, (b_in[left], b_out[left]), 1.0)
    table = Table(float(ior), n_mu, n_phi, np.cumsum(counts / rays, axis=1), rays)
    return Table(table.ior, n_mu, n_phi, table.cdf, rays, model_error(e, table, s=s, seed=seed + 1))


PROBE_RAYS = 1000     # rays of each probe beam (`model_error`)


def _plain_exit(mu: np.ndarray, ior: float) -> np.ndarray:
    """Share of light inside a solid of index `ior` travelling at |cos θ| = mu to a plain face that leaves it into
    the air (unpolarized Fresnel; 0 under total internal reflection)."""
    r, _ = _fresnel(np.asarray(mu, float), np.full(np.shape(mu), float(ior)), np.ones(np.shape(mu)))
    return 1.0 - r


def model_error(e: Microstructure, table: Table, *, rays: int | None = None, seed: int = 1, s=None) -> dict:
    """The table's deviation from the exact model (module docstring): probe beams from each arriving bin's
    azimuth centre at its |cos θ| edges (1e-3 inside) and middle, both sides, `rays` each (default `PROBE_RAYS`),
    traced exactly and set against the table's row. Answers, per side (``{"air": ..., "solid": ...}``), the worst
    probe's ``deviation`` (table − exact, a share of the flux that meets the element) and its ``stderr`` (the exact
    probe's and the table row's Monte Carlo errors combined), with where (``side``, ``theta_deg``, ``phi_deg``),
    ``probes``, ``probe_rays``, the ``exact`` share there and what was measured (``measure``)."""
    rays = PROBE_RAYS if rays is None else int(rays)
    rng = np.random.default_rng(seed)
    n_mu, n_phi, ior = table.n_mu, table.n_phi, table.ior
    u0, v0, su, sv, lu, lv = _patch(e)
    if s is None:
        s = _scene(e, lu, lv, 10.0 * e.h + 1.0)
    half = n_mu * n_phi
    # what each leaving bin is worth on each side's measure: through a plain face, the mean over the bin's |cos θ|
    # (its directions are drawn uniformly over the bin); into the air, 1
    grid = (np.arange(400) + 0.5) / 400
    exit_bin = np.array([_plain_exit((i + grid) / n_mu, ior).mean() for i in range(n_mu)])
    worth = {"air": np.concatenate([np.zeros(half), np.repeat(exit_bin, n_phi)]),
             "solid": np.concatenate([np.ones(half), np.zeros(half)])}
    p = table.probabilities
    probes = []
    for side in SIDES:
        for im in range(n_mu):
            for m in (im / n_mu + 1e-3, (im + 0.5) / n_mu, (im + 1) / n_mu - 1e-3):
                for ip in range(n_phi):
                    probes.append((side, max(m, MU_MIN), (ip + 0.5) / n_phi * 2.0 * math.pi, im * n_phi + ip))
    k = len(probes)
    mu = np.repeat([x[1] for x in probes], rays)
    phi = np.repeat([x[2] for x in probes], rays)
    up = np.repeat([x[0] == "air" for x in probes], rays)
    sn = np.sqrt(1.0 - mu * mu)
    w = np.column_stack([sn * np.cos(phi), sn * np.sin(phi), np.where(up, mu, -mu)])   # where the light comes from
    d = -w
    top = (e.h if e.sign > 0 else 0.0) + 1e-4
    bottom = -(e.h if e.sign < 0 else 0.0) - 1e-4
    z = np.where(up, top, bottom)
    o = np.column_stack([u0 + rng.random(len(d)) * su, v0 + rng.random(len(d)) * sv, np.zeros(len(d))]) + (
        z / d[:, 2])[:, None] * d
    w_out, left = trace(s, ior, o, d, rng)
    value = np.where(w_out[:, 2] < 0.0, _plain_exit(np.abs(w_out[:, 2]), ior), 0.0)   # into the solid, then out of it
    value = np.where(up, value, (w_out[:, 2] > 0.0).astype(float)) * left           # or out into the air
    per = value.reshape(k, rays)
    exact, exact_var = per.mean(axis=1), per.var(axis=1) / rays
    dev = np.empty(k)
    se = np.empty(k)
    for j, (side, _, _, b) in enumerate(probes):
        row = b + (half if side == "solid" else 0)
        c = worth[side]
        mean = float(p[row] @ c)
        dev[j] = mean - exact[j]
        se[j] = math.sqrt(max(0.0, float(p[row] @ (c * c)) - mean * mean) / table.rays + exact_var[j])
    out: dict[str, dict] = {}
    for name in SIDES:
        idx = [i for i, x in enumerate(probes) if x[0] == name]
        j = idx[int(np.argmax(np.abs(dev[idx])))]
        _, m, f, _ = probes[j]
        out[name] = _error_dict(float(dev[j]), float(se[j]), name, math.degrees(math.acos(m)), math.degrees(f),
                                len(idx), rays, float(exact[j]))
    return out
