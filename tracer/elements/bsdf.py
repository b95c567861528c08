"""An element's tabulated BSDF: how its micro-structured face scatters, computed once from the exact model.

The table is the element's ``bsdf`` model (docs/DESIGN.md "Optical elements with an inside"): for a support of a solid
of index ``ior`` in air, the probability that light arriving from direction bin ``i`` leaves into direction bin ``o``.
Directions are binned on both sides of the support, in its frame (u, v, n: `tracer.elements.support`): side 0 the
air side (w > 0 for the leaving light, arriving light travels down), side 1 the solid's; on each side ``n_mu``
bins in |cos theta| by ``n_phi`` in the azimuth from u. On the air side the |cos theta| bins are uniform (equal solid
angles); on the solid's, ``split`` of them are uniform below the critical angle's |cos| mu_c = sqrt(1 - 1/n^2) and the
rest above it (`mu_edges`), so that no bin holds directions on both sides of total internal reflection: drawn
uniformly over such a bin, a direction would cross the critical angle where the exact model's light does not (the
worst probe of a dotted plate's table was off by 0.3-0.4 of the flux there; tables kept before, ``split`` 0, keep
uniform bins). Bin index
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

A density map's face varies from place to place, so its model is one table per fill level (`LEVELS`, evenly spaced from
0, a plain face, to 1), each traced on a patch of the same features placed at that uniform fill (the map's pitch,
placement and seed); a photon meeting the support reads the map's fill f where it lands and scatters by the table of
level k or k + 1 around f (k + 1 with probability f (K − 1) − k), so the face scatters as the mixture of its two nearest
levels. Its error is the worst over the levels and the fills halfway between them, where the mixture of the two tables
around stands for the features placed at that fill (``fill`` says which). Printed features (a material of their own,
`tracer.elements.microstructure`) reflect diffusely with their reflectance and absorb the rest, as in the exact model; a
photon they absorb leaves nothing, so a row's sum is the light that is not absorbed.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from tracer.elements import features as fx
from tracer.elements.checks import ElementError
from tracer.elements.microstructure import Microstructure, prepare

N_MU, N_PHI, RAYS = 6, 8, 4000
LEVELS = 5            # a density map's tables: fill 0, 0.25, 0.5, 0.75, 1
MAX_BOUNCES = 64


@dataclass(frozen=True)
class Table:
    """A tabulated BSDF: ``cdf`` (nb, nb) float64 running sums of each arriving bin's row; its bins and index;
    ``error``: how far it is off, measured against the exact model when it was made (`model_error`: per side; None
    for a table kept before it was measured); ``levels``: how many tables ``cdf`` stacks, one per fill level of a
    density map (evenly spaced from 0 to 1), 1 for a periodic layout's; ``split``: how many of the solid side's
    |cos θ| bins lie below its critical angle's (`mu_edges`; 0: uniform bins, as tables were kept before)."""

    ior: float
    n_mu: int
    n_phi: int
    cdf: np.ndarray
    rays: int
    error: dict | None = None
    levels: int = 1
    split: int = 0

    @property
    def bins(self) -> int:
        return 2 * self.n_mu * self.n_phi

    def edges(self, side: int) -> np.ndarray:
        """(n_mu + 1,) the |cos θ| edges of side `side`'s bins (`mu_edges`)."""
        return mu_edges(self.n_mu, self.ior, self.split if side == 1 else 0)

    @property
    def probabilities(self) -> np.ndarray:
        """(nb, nb) the probability of each (arriving, leaving) pair of bins."""
        return np.diff(self.cdf, axis=1, prepend=0.0)

    def arrays(self) -> dict[str, np.ndarray]:
        out = {"cdf": self.cdf,
               "params": np.array([self.ior, self.n_mu, self.n_phi, self.rays, self.levels, self.split], np.float64)}
        if self.error is not None:
            out["error"] = np.array([[e["deviation"], e["stderr"], SIDES.index(e["side"]), e["theta_deg"],
                                      e["phi_deg"], e["probes"], e["probe_rays"], e["exact"], e.get("fill", np.nan)]
                                     for e in (self.error[side] for side in SIDES)], np.float64)
        return out

    @classmethod
    def from_arrays(cls, arrays) -> Table:
        """The table `arrays` gave (as kept before levels, fills and splits, too: one level, no fill, uniform bins)."""
        p = arrays["params"]
        error = None
        if "error" in getattr(arrays, "files", arrays):
            error = {}
            for row in np.asarray(arrays["error"], np.float64):
                e = [float(x) for x in row]
                fill = e[8] if len(e) > 8 and math.isfinite(e[8]) else None
                error[SIDES[int(e[2])]] = _error_dict(e[0], e[1], SIDES[int(e[2])], e[3], e[4], int(e[5]), int(e[6]),
                                                      e[7], fill)
        return cls(float(p[0]), int(p[1]), int(p[2]), np.asarray(arrays["cdf"], np.float64), int(p[3]), error,
                   int(p[4]) if len(p) > 4 else 1, int(p[5]) if len(p) > 5 else 0)


SIDES = ("air", "solid")
MEASURES = {"air": "share of a beam from the air that crosses the element and a plain parallel face of the solid",
            "solid": "share of a beam from inside the solid that leaves through the element into the air"}


def _error_dict(dev: float, se: float, side: str, theta: float, phi: float, probes: int, rays: int,
                exact: float, fill: float | None = None) -> dict:
    out = {"deviation": dev, "stderr": se, "side": side, "theta_deg": theta, "phi_deg": phi, "probes": probes,
           "probe_rays": rays, "exact": exact, "measure": MEASURES[side]}
    if fill is not None:   # a density map's table: the fill level where it is furthest off
        out["fill"] = fill
    return out


def critical_mu(ior: float) -> float:
    """|cos θ| of the critical angle inside a solid of index `ior` in air: sqrt(1 - 1/n²) (0 for n = 1)."""
    return math.sqrt(max(0.0, 1.0 - 1.0 / (float(ior) * float(ior))))


def split_for(n_mu: int, ior: float) -> int:
    """How many of the solid side's `n_mu` bins lie below its critical angle's |cos|: in proportion to that |cos|,
    at least one on each side of it (0, uniform bins, for n = 1)."""
    c = critical_mu(ior)
    return 0 if c <= 0.0 or n_mu < 2 else int(min(max(round(n_mu * c), 1), n_mu - 1))


def mu_edges(n_mu: int, ior: float, split: int) -> np.ndarray:
    """(n_mu + 1,) |cos θ| edges of one side's bins: uniform from 0 to 1 (`split` 0), or `split` uniform bins up to
    the critical angle's |cos| and the rest uniform above it."""
    if split <= 0:
        return np.linspace(0.0, 1.0, n_mu + 1)
    c = critical_mu(ior)
    return np.concatenate([np.linspace(0.0, c, split + 1), np.linspace(c, 1.0, n_mu - split + 1)[1:]])


def bin_of(w: np.ndarray, n_mu: int, n_phi: int, solid: np.ndarray | None = None) -> np.ndarray:
    """Bin of leaving directions ``w`` (k, 3) in the support's frame (u, v, n): side 0 where w_n > 0; `solid`: the
    solid side's |cos θ| edges (`mu_edges`; None: uniform)."""
    side = (w[:, 2] <= 0.0).astype(np.int64)
    m = np.abs(w[:, 2])
    mu = np.minimum((m * n_mu).astype(np.int64), n_mu - 1)
    if solid is not None:
        mu = np.where(side == 1, np.clip(np.searchsorted(solid, m, side="right") - 1, 0, n_mu - 1), mu)
    phi = np.mod(np.arctan2(w[:, 1], w[:, 0]), 2.0 * math.pi)
    ip = np.minimum((phi / (2.0 * math.pi) * n_phi).astype(np.int64), n_phi - 1)
    return side * n_mu * n_phi + mu * n_phi + ip


def sample_in_bin(b: np.ndarray, n_mu: int, n_phi: int, r1: np.ndarray, r2: np.ndarray,
                  solid: np.ndarray | None = None) -> np.ndarray:
    """Leaving directions (k, 3) uniform over the solid angle of bins ``b`` (`solid` as `bin_of` takes it)."""
    side, rest = np.divmod(b, n_mu * n_phi)
    im, ip = np.divmod(rest, n_phi)
    mu = (im + r1) / n_mu
    if solid is not None:
        mu = np.where(side == 1, solid[im] + r1 * (solid[im + 1] - solid[im]), mu)
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
    """(u0, v0, su, sv) of the patch rays land on and (lu, lv) of the support, mm (periodic layouts and density
    maps: a density map's levels are placed over the whole support, `_level`)."""
    if e.layout not in (fx.GRID, fx.HEX, fx.DENSITY):
        raise ElementError("model: a tabulated BSDF is built for periodic layouts (grid, hex) and density maps; a "
                           "point list or a close-packed layout is not one: use the exact model")
    cu, cv = e.cell
    k = max(20, int(math.ceil(0.5 / min(cu, cv))))     # at least 20 cells and 0.5 mm
    u0 = MARGIN_MM - math.fmod(MARGIN_MM, cu)            # a whole number of cells from the support's corner
    v0 = MARGIN_MM - math.fmod(MARGIN_MM, cv)
    return u0, v0, k * cu, k * cv, u0 + k * cu + MARGIN_MM, v0 + k * cv + MARGIN_MM


def _level(e: Microstructure, fill: float, lu: float, lv: float) -> Microstructure:
    """The density map's features placed at a uniform `fill` over a support lu x lv mm (its pitch, placement and
    seed): what one level of its table is traced on."""
    return prepare({**e.body, "layout": {**e.body["layout"], "origin_mm": [0.0, 0.0], "size_mm": [lu, lv],
                                         "fill": [[float(fill)]]}})


def _fills(e: Microstructure) -> list[float | None]:
    """The fill of each table: none for a periodic layout's one, `LEVELS` uniform fills from 0 to 1 for a density
    map's."""
    return [None] if e.layout != fx.DENSITY else [k / (LEVELS - 1) for k in range(LEVELS)]


def _levels(e: Microstructure, lu: float, lv: float) -> list[tuple[float | None, Microstructure]]:
    """(fill, patch element) of each table (`_fills`): the element itself for a periodic layout."""
    return [(fill, e if fill is None else _level(e, fill, lu, lv)) for fill in _fills(e)]


def _scene(e: Microstructure, lu: float, lv: float, depth: float):
    from tracer.scene import Scene
    from tracer.warmup import box

    s = Scene()
    v, t = box([0.0, 0.0, -depth], [lu, lv, 0.0])
    part = s.add_instance(s.add_geometry(v, t), np.eye(4))
    s.set_element(part, e, facing=[0, 0, 1], mm_per_unit=1.0)
    s.commit()
    return s


def _diffuse(f: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Directions (k, 3) cosine-distributed about the unit normals `f` (k, 3): a Lambertian reflection."""
    r1, r2 = rng.random(len(f)), rng.random(len(f))
    t = np.where(np.abs(f[:, :1]) < 0.9, np.cross(f, [1.0, 0.0, 0.0]), np.cross(f, [0.0, 1.0, 0.0]))
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    b = np.cross(f, t)
    sr, phi = np.sqrt(r1), 2.0 * math.pi * r2
    return (sr * np.cos(phi))[:, None] * t + (sr * np.sin(phi))[:, None] * b + np.sqrt(1.0 - r1)[:, None] * f


def trace(s, ior: float, o: np.ndarray, d: np.ndarray, rng: np.random.Generator,
          surface: tuple[int, float] = (fx.MAT_PART, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Leaving directions (k, 3) of photons from points ``o`` along ``d`` through scene `s` (`_scene`: mm, the
    support's frame u, v, n = x, y, z, the face at z = 0 over a solid below), and whether each left (False: absorbed,
    or still inside after MAX_BOUNCES). A photon leaves where it meets nothing (upwards, into the air) or the solid's
    other faces (down into it); at the face it is reflected or refracted (unpolarized Fresnel), at the features too,
    unless they have a `surface` of their own (``(features.MAT_LAMBERTIAN, reflectance)`` or ``MAT_BLACK``): then
    reflected diffusely on the side it came from with that reflectance, absorbed otherwise."""
    o = o.copy()
    d = d.copy()
    alive = np.ones(len(o), bool)
    done = np.zeros(len(o), bool)
    own, rho = int(surface[0]), float(surface[1]) if surface[0] == fx.MAT_LAMBERTIAN else 0.0
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
        printed = h.primitive[~leave] < -1 if own != fx.MAT_PART else np.zeros(len(k), bool)
        if printed.any():   # a feature's own surface: diffuse reflection on the arriving side, or absorbed
            kept = rng.random(len(k)) < rho
            alive[k[printed & ~kept]] = False
            refl = np.where(printed, True, refl)
            out[printed] = _diffuse(f[printed], rng)
        out /= np.linalg.norm(out, axis=1, keepdims=True)
        d[k] = out
        o[k] = p[~leave] + np.where(refl, 1e-9, -1e-9)[:, None] * f   # on the side it goes on from
    return d, done


def _rows(e: Microstructure, s, ior: float, n_mu: int, n_phi: int, rays: int, rng: np.random.Generator,
          patch: tuple[float, float, float, float], split: int) -> np.ndarray:
    """One table's running sums (nb, nb): `rays` photons per arriving bin over the `patch` (u0, v0, su, sv) of
    element `e` on scene `s`, the solid side's bins split at its critical angle by `split` (module docstring)."""
    solid = mu_edges(n_mu, ior, split) if split else None
    u0, v0, su, sv = patch
    nb = 2 * n_mu * n_phi
    counts = np.zeros((nb, nb))
    b_in = np.repeat(np.arange(nb), rays)
    # an arriving bin is the reversed direction's: side 0 comes from the air (travels down), side 1 from the solid
    w = sample_in_bin(b_in, n_mu, n_phi, rng.random(len(b_in)), rng.random(len(b_in)), solid)
    w[:, 2] = np.copysign(np.maximum(np.abs(w[:, 2]), MU_MIN), w[:, 2])
    d = -w / np.linalg.norm(w, axis=1, keepdims=True)
    top = (e.h if e.sign > 0 else 0.0) + 1e-4
    bottom = -(e.h if e.sign < 0 else 0.0) - 1e-4
    z = np.where(b_in < nb // 2, top, bottom)
    pu = u0 + rng.random(len(b_in)) * su
    pv = v0 + rng.random(len(b_in)) * sv
    # start just off the face, back along d from a point of the patch's plane (it may meet a feature before it)
    o = np.column_stack([pu, pv, np.zeros(len(b_in))]) + (z / d[:, 2])[:, None] * d
    out, left = trace(s, ior, o, d, rng, (e.material, e.reflectance))
    b_out = bin_of(out, n_mu, n_phi, solid)
    np.add.at(counts, (b_in[left], b_out[left]), 1.0)
    return np.cumsum(counts / rays, axis=1)


def tabulate(e: Microstructure, ior: float, *, n_mu: int = N_MU, n_phi: int = N_PHI, rays: int | None = None,
             seed: int = 0, split: bool = True) -> Table:
    """The element's BSDF on a solid of index `ior` in air, traced through its exact geometry (module docstring):
    one table, or a density map's `LEVELS`; `rays` per arriving bin (default `RAYS`, read when called); `split`:
    the solid side's bins split at its critical angle (`split_for`; False: uniform bins, as before 2026-12-08)."""
    rays = RAYS if rays is None else int(rays)
    if isinstance(ior, bool) or not (isinstance(ior, int | float) and math.isfinite(ior) and 1.0 <= ior <= 4.0):
        raise ElementError(f"ior must be a number in [1, 4] for a tabulated BSDF, got {ior!r}")
    rng = np.random.default_rng(seed)
    u0, v0, su, sv, lu, lv = _patch(e)
    levels = _levels(e, lu, lv)
    scenes = [_scene(p, lu, lv, 10.0 * e.h + 1.0) for _, p in levels]
    k = split_for(n_mu, float(ior)) if split else 0
    cdf = np.concatenate([_rows(p, s, float(ior), n_mu, n_phi, rays, rng, (u0, v0, su, sv), k)
                          for (_, p), s in zip(levels, scenes, strict=True)])
    table = Table(float(ior), n_mu, n_phi, cdf, rays, levels=len(levels), split=k)
    return dataclasses.replace(table, error=model_error(e, table, s=scenes, seed=seed + 1))


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
    ``probes``, ``probe_rays``, the ``exact`` share there and what was measured (``measure``); for a density map's
    levels and the fills halfway between them (the features placed at that fill, against the even mixture of the
    two tables around it, as the transport draws them: how far the tables' reading of a fill between levels is off)
    the worst over them all, and its ``fill``. `s`: the patches' scenes, as `tabulate` made them (made here where
    None)."""
    rays = PROBE_RAYS if rays is None else int(rays)
    rng = np.random.default_rng(seed)
    u0, v0, su, sv, lu, lv = _patch(e)
    fills = _fills(e)
    scenes = s if isinstance(s, list) else [s] if s is not None else [None] * len(fills)
    nb = table.bins
    cdfs = [table.cdf[k * nb:(k + 1) * nb] for k in range(len(fills))]
    checks = list(zip(fills, cdfs, scenes, strict=True))
    for k in range(len(fills) - 1):   # a density map: halfway between two levels
        checks.append(((k + 0.5) / (len(fills) - 1), 0.5 * (cdfs[k] + cdfs[k + 1]), None))
    worst: dict[str, dict] = {}
    for fill, cdf, scene in checks:
        one = Table(table.ior, table.n_mu, table.n_phi, cdf, table.rays, split=table.split)
        if scene is None:   # the patch's features placed (a level's made by `tabulate` are passed in `s`)
            scene = _scene(e if fill is None else _level(e, fill, lu, lv), lu, lv, 10.0 * e.h + 1.0)
        # a level's features are `e`'s (its feature, relief and material), placed at another fill
        for side, err in _probe_error(e, one, scene, rays, rng, (u0, v0, su, sv), fill).items():
            if side not in worst or abs(err["deviation"]) > abs(worst[side]["deviation"]):
                worst[side] = err
    return worst


def _probe_error(e: Microstructure, table: Table, s, rays: int, rng: np.random.Generator,
                 patch: tuple[float, float, float, float], fill: float | None) -> dict:
    """`model_error` of one table (one element or one level) on its patch's scene `s`."""
    n_mu, n_phi, ior = table.n_mu, table.n_phi, table.ior
    u0, v0, su, sv = patch
    half = n_mu * n_phi
    # what each leaving bin is worth on each side's measure: through a plain face, the mean over the bin's |cos θ|
    # (its directions are drawn uniformly over the bin); into the air, 1
    grid = (np.arange(400) + 0.5) / 400
    solid = table.edges(1)
    exit_bin = np.array([_plain_exit(solid[i] + grid * (solid[i + 1] - solid[i]), ior).mean() for i in range(n_mu)])
    worth = {"air": np.concatenate([np.zeros(half), np.repeat(exit_bin, n_phi)]),
             "solid": np.concatenate([np.ones(half), np.zeros(half)])}
    p = table.probabilities
    probes = []
    for side in SIDES:
        edges = table.edges(SIDES.index(side))
        for im in range(n_mu):
            lo, hi = edges[im], edges[im + 1]
            for m in (lo + 1e-3, 0.5 * (lo + hi), hi - 1e-3):
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
    w_out, left = trace(s, ior, o, d, rng, (e.material, e.reflectance))
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
                                len(idx), rays, float(exact[j]), fill)
    return out
