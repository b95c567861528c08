"""A micro-structured face as a prepared model: its feature, its relief and its layout, checked and packed once.

The body (docs/DESIGN.md "Optical elements with an inside"; lengths in mm, on the support's u-v frame)::

    {"type": "microstructure",
     "feature": {"shape": "dome", "radius_mm": r, "height_mm": h}          (a spherical cap, h <= r)
              | {"shape": "pyramid", "base_mm": b, "height_mm": h}         (square base, sides along u and v)
              | {"shape": "prism", "base_mm": b, "apex_deg": 90},          (a ridge along v; layout grid only)
              | {"shape": "corner_cube", "side_mm": s},                    (three perpendicular faces meeting at
                                   the apex, axis along the normal, over an equilateral triangle of side s with a
                                   vertex towards +v; height s / sqrt(6): a retroreflector)
              | {"shape": "mesh", "vertices_mm": [[u, v, w], ...], "triangles": [[i, j, k], ...]}   (any closed
                                   convex solid standing on its base at w = 0: `tracer.elements.shapes.mesh`)
     "relief": "bump" | "pit",
     "material": null                                              (the features take the part's own material)
               | {"type": "lambertian", "reflectance": r} | {"type": "black"},   (their own surface: a printed dot)
     "layout": {"type": "grid", "pitch_mm": [pu, pv]} | {"type": "hex", "pitch_mm": p}         (domes)
             | {"type": "density", "origin_mm": [u0, v0], "size_mm": [su, sv], "fill": [[...], ...], "seed": 1,
                "pitch_mm": p,        (a lattice of pitch p, default the feature's base, keeping its map cell's fill
                                       of its sites, rows along v from v0, columns along u)
                "placement": "blue_noise" | "random"}   (which sites: by error diffusion, the default, or each site
                                       alone with probability fill; `tracer.elements.placement`)
             | {"type": "points", "uv_mm": [[u, v], ...]}
             | {"type": "triangular"}}    (triangles close-packed, every other one turned 180 degrees: corner cubes
                                           with no gap between them; rows along u from the support's corner)

`prepare` checks it (`ElementError` naming the field and what to do) and packs what the inner tracer
(:mod:`tracer.elements.features`) walks: nothing per feature for the periodic layouts (their memory does not grow with
the count), one bit per lattice site for a density map, 12 to 20 bytes per listed point; a mesh feature's face
planes once (32 bytes each), whatever the count. The same body gives the same
`Microstructure.id` (a SHA-256 of its canonical JSON), so a library keeps one prepared model per body.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tracer.elements import features as fx
from tracer.elements.checks import ElementError, check_fields, number, pair
from tracer.elements.placement import PLACEMENTS, diffuse
from tracer.elements.shapes.dispatch import KINDS as SHAPE_KINDS
from tracer.elements.shapes.dispatch import SHAPE_OF_NAME

FEATURE_MATERIALS = ("lambertian", "black")
LAYOUTS = {"grid": fx.GRID, "hex": fx.HEX, "density": fx.DENSITY, "points": fx.POINTS, "triangular": fx.TRIANGULAR}
MAX_SITES = 4_000_000_000     # a density lattice's sites (one bit each: 500 MB)
#: What preparing a density lattice costs, per site: its kept bit (1/8 byte, packed a band at a time, so no byte per
#: site is ever held: tracemalloc's peak 0.18 B/site over 4e8 sites, 1.17 before), and the rate per placement:
#: drawing and comparing one random number (measured 8.7e7 to 1.1e8 sites/s over 1e8 and 4e8 sites on the development
#: machine, busy), diffusing the error (7.7e7 sites/s over 1.6e7 sites); each taken at half, as a slower machine's.
#: Blue noise also holds 8 bytes per site of one row (`placement`).
SITE_BYTES = 0.125
SITES_PER_SECOND = {"random": 5.0e7, "blue_noise": 3.8e7}
ROW_SITE_BYTES = {"random": 0, "blue_noise": 8}
BAND_BYTES = 64 << 20         # a band's temporaries: BAND_SITE_BYTES per site (indices, random numbers, fills, flags)
BAND_SITE_BYTES = 49
#: The most one request may cost to prepare: memory of the kept bits (and the band's temporaries beside them) and
#: seconds at `SITES_PER_SECOND`; a larger lattice is refused before any work (`density_cost`).
MAX_PREPARE_BYTES = 256 << 20
MAX_PREPARE_SECONDS = 15.0
MAX_POINTS = 20_000_000       # listed features
MAX_MAP_CELLS = 4_000_000     # cells of a density map


@dataclass(frozen=True, eq=False)
class Microstructure:
    """A prepared micro-structured face. Lengths in mm.

    ``a``: the feature's half base (a dome's base radius); ``h`` its height; ``rs`` a dome's sphere radius;
    ``sign`` +1 for a bump, -1 for a pit (a corner cube: ``a`` its circumradius, ``rs`` its inradius);
    ``material`` the features' own surface (`features.MAT_PART`: the part's; `MAT_BLACK`, `MAT_LAMBERTIAN`) and
    ``reflectance`` its reflectance; ``cell`` the layout's cell (mm, (2,)), ``origin`` its first corner (mm);
    ``cells`` (nu, nv) for the listed layouts (zero: the periodic ones, counted on their support);
    ``bits`` (uint8) the kept lattice sites of a density map; ``uv`` (P, 2) float32 listed centres with ``bins``
    (int32 starts, nu nv + 1) and ``items`` (int32) their ids by cell; ``faces`` (K, 4) float64 the feature's face
    planes (a mesh's: `tracer.elements.shapes.base`).
    """

    id: str
    body: dict
    shape: int
    a: float
    h: float
    rs: float
    sign: float
    layout: int
    cell: tuple[float, float]
    origin: tuple[float, float] = (0.0, 0.0)
    cells: tuple[int, int] = (0, 0)
    bits: np.ndarray = field(default_factory=lambda: np.zeros(0, np.uint8))
    uv: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), np.float32))
    bins: np.ndarray = field(default_factory=lambda: np.zeros(1, np.int32))
    items: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    features: int | None = None      # None: periodic, as many as its support holds
    prepare_seconds: float = 0.0
    material: int = fx.MAT_PART
    reflectance: float = 0.0
    faces: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))

    @property
    def nbytes(self) -> int:
        """Memory the prepared features take (bytes); a periodic layout's is constant."""
        return int(self.bits.nbytes + self.uv.nbytes + self.bins.nbytes + self.items.nbytes + self.faces.nbytes)

    def summary(self) -> dict[str, Any]:
        """What a library lists: id, type, features (None: periodic), bytes, prepare_seconds."""
        return {"id": self.id, "type": "microstructure", "features": self.features, "bytes": self.nbytes,
                "prepare_seconds": self.prepare_seconds}

    def arrays(self) -> dict[str, np.ndarray]:
        """Its packed arrays and parameters, for a library file (`from_arrays` reads them back)."""
        return {"body": np.frombuffer(json.dumps(self.body, sort_keys=True).encode(), np.uint8),
                "bits": self.bits, "uv": self.uv, "bins": self.bins, "items": self.items, "faces": self.faces,
                "params": np.array([self.a, self.h, self.rs, self.sign, *self.cell, *self.origin,
                                    self.prepare_seconds, self.reflectance]),
                "ints": np.array([self.shape, self.layout, *self.cells, -1 if self.features is None else self.features,
                                  self.material], np.int64)}

    @classmethod
    def from_arrays(cls, arrays: Any) -> Microstructure:
        """A model saved by `arrays` (an ``np.load`` of them), as it was: nothing is prepared again."""
        body = json.loads(bytes(arrays["body"]).decode())
        p = arrays["params"]
        ints = [int(x) for x in arrays["ints"]]
        return cls(element_id(body), body, ints[0], float(p[0]), float(p[1]), float(p[2]), float(p[3]), ints[1],
                   (float(p[4]), float(p[5])), (float(p[6]), float(p[7])), (ints[2], ints[3]),
                   np.asarray(arrays["bits"], np.uint8), np.asarray(arrays["uv"], np.float32),
                   np.asarray(arrays["bins"], np.int32), np.asarray(arrays["items"], np.int32),
                   None if ints[4] < 0 else ints[4], float(p[8]),
                   ints[5] if len(ints) > 5 else fx.MAT_PART, float(p[9]) if len(p) > 9 else 0.0,
                   np.asarray(arrays["faces"], np.float64).reshape(-1, 4) if "faces" in arrays else np.zeros((0, 4)))


def element_id(body: dict, uv: np.ndarray | None = None) -> str:
    """The id of a checked body: SHA-256 of its canonical JSON (the same body, the same id). A point list enters it
    as the SHA-256 of its centres as little-endian float64 (`uv`, (P, 2), where the caller has them): formatting 10^6
    points as JSON took longer than preparing them."""
    layout = body.get("layout")
    if isinstance(layout, dict) and layout.get("type") == "points":
        pts = _uv_array(layout["uv_mm"]) if uv is None else uv
        digest = hashlib.sha256(np.ascontiguousarray(pts, "<f8").tobytes()).hexdigest()
        body = {**body, "layout": {**layout, "uv_mm": {"float64_sha256": digest, "count": len(pts)}}}
    return hashlib.sha256(json.dumps(body, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def _uv_array(x: Any) -> np.ndarray:
    """Listed centres as float64 (P, 2): from a list of [u, v] pairs (read flat, without a Python float per element
    kept) or an array. `ElementError` where they are not pairs of numbers."""
    if isinstance(x, np.ndarray):
        uv = x.astype(np.float64, copy=False)
    elif isinstance(x, list | tuple):
        try:
            if any(len(p) != 2 for p in x):
                raise TypeError
            uv = np.fromiter(itertools.chain.from_iterable(x), np.float64, count=2 * len(x)).reshape(-1, 2)
        except (TypeError, ValueError):
            raise ElementError("layout.uv_mm must be a list of [u, v] pairs in mm") from None
    else:
        raise ElementError("layout.uv_mm must be a list of [u, v] pairs in mm")
    if uv.ndim != 2 or uv.shape[1:] != (2,) or len(uv) == 0:
        raise ElementError(f"layout.uv_mm must be a non-empty list of [u, v] pairs in mm, got shape {uv.shape}")
    return uv


def _feature(f: Any) -> tuple[dict, int, float, float, float, np.ndarray]:
    """The checked feature: (canonical body, shape id, a, h, rs, face planes) in mm (`tracer.elements.shapes`)."""
    if not isinstance(f, dict):
        raise ElementError(f"feature must be an object with a 'shape' ({sorted(SHAPE_OF_NAME)}), got {f!r}"[:300])
    name = f.get("shape")
    if name not in SHAPE_OF_NAME:
        raise ElementError(f"feature.shape {name!r} is unknown; known: {sorted(SHAPE_OF_NAME)}"[:300])
    shape = SHAPE_OF_NAME[name]
    module = SHAPE_KINDS[shape]
    check_fields(f, "feature", {"shape", *module.FIELDS}, set())
    canon, a, h, rs, faces = module.parse(f)
    return canon, shape, a, h, rs, faces


def prepare(body: Any) -> Microstructure:
    """Check an element body and prepare its model (see the module docstring).

    Raises
    ------
    ElementError
        Not an object, unknown or missing field, a value out of range, a pitch smaller than the feature, a fill
        outside [0, 1], features of a point list that overlap; each message names the field.
    """
    t0 = time.perf_counter()
    if not isinstance(body, dict):
        raise ElementError(f"an element is an object {{'type': 'microstructure', ...}}, got {type(body).__name__}")
    if body.get("type") != "microstructure":
        raise ElementError(f"element type {body.get('type')!r} is unknown; known: ['microstructure']")
    check_fields(body, "element", {"type", "feature", "layout"}, {"relief", "material"})
    material, mat, rho = _material(body.get("material"))
    relief = body.get("relief", "bump")
    if relief not in ("bump", "pit"):
        raise ElementError(f"relief must be 'bump' (raised from the surface) or 'pit' (cut into it), got {relief!r}")
    feature, shape, a, h, rs, faces = _feature(body["feature"])
    layout = body["layout"]
    if not isinstance(layout, dict) or layout.get("type") not in LAYOUTS:
        got = layout.get("type") if isinstance(layout, dict) else layout
        raise ElementError(f"layout.type {got!r} is unknown; known: {sorted(LAYOUTS)}"[:300])
    lay = LAYOUTS[layout["type"]]
    takes = SHAPE_KINDS[shape].LAYOUTS
    if layout["type"] not in takes:
        name = SHAPE_KINDS[shape].NAME
        ridge = f" ({name}s are ridges across the support; a grid's pitch_mm[0] runs along u)" \
            if SHAPE_KINDS[shape].RIDGE else ""
        raise ElementError(f"layout: a {layout['type']!r} layout does not take the feature shape {name!r}; it takes "
                           f"{list(takes)}{ridge}")
    common = {"type": "microstructure", "relief": relief, "material": material, "feature": feature}
    sign = 1.0 if relief == "bump" else -1.0
    args = (shape, a, h, rs, sign, mat, rho, faces)
    if lay == fx.GRID:
        return _grid(layout, common, args, t0)
    if lay == fx.HEX:
        check_fields(layout, "layout", {"type", "pitch_mm"}, set())
        p = _pitch(layout["pitch_mm"], "layout.pitch_mm", a)
        canon = {**common, "layout": {"type": "hex", "pitch_mm": p}}
        return _model(canon, args, fx.HEX, (p, p * math.sqrt(3.0) / 2.0), t0)
    if lay == fx.DENSITY:
        return _density(layout, common, args, t0)
    if lay == fx.TRIANGULAR:   # the base's side from its circumradius; rows of height side sqrt(3)/2
        check_fields(layout, "layout", {"type"}, set())
        side = a * math.sqrt(3.0)
        return _model({**common, "layout": {"type": "triangular"}}, args, fx.TRIANGULAR,
                      (side / 2.0, side * math.sqrt(3.0) / 2.0), t0)
    return _points(layout, common, args, t0)


def _material(m: Any) -> tuple[dict | None, int, float]:
    """The features' own surface: (canonical body, `features.MAT_*`, reflectance); None: the part's material."""
    if m is None:
        return None, fx.MAT_PART, 0.0
    if not isinstance(m, dict) or m.get("type") not in FEATURE_MATERIALS:
        got = m.get("type") if isinstance(m, dict) else m
        raise ElementError(f"material.type {got!r} is not a feature material; known: {list(FEATURE_MATERIALS)} (or "
                           f"null: the part's own material)"[:300])
    if m["type"] == "black":
        check_fields(m, "material", {"type"}, set())
        return {"type": "black"}, fx.MAT_BLACK, 0.0
    check_fields(m, "material", {"type", "reflectance"}, set())
    rho = number(m["reflectance"], "material.reflectance", lo_open=False, hi=1.0)
    return {"type": "lambertian", "reflectance": rho}, fx.MAT_LAMBERTIAN, rho


def _pitch(x: Any, where: str, a: float) -> float:
    p = number(x, where)
    if p < 2.0 * a:
        raise ElementError(f"{where} ({p:g} mm) is smaller than the feature ({2 * a:g} mm across): features would "
                           f"overlap; give a pitch of at least {2 * a:g} mm")
    return p


def _model(canon: dict, args: tuple, layout: int, cell: tuple[float, float], t0: float, uv64: np.ndarray | None = None,
           **arrays: Any) -> Microstructure:
    shape, a, h, rs, sign, mat, rho, faces = args
    return Microstructure(element_id(canon, uv64), canon, shape, a, h, rs, sign, layout, cell, **arrays, faces=faces,
                          prepare_seconds=time.perf_counter() - t0, material=mat, reflectance=rho)


def _grid(layout: dict, common: dict, args: tuple, t0: float) -> Microstructure:
    check_fields(layout, "layout", {"type", "pitch_mm"}, set())
    shape, a = args[0], args[1]
    ridge = SHAPE_KINDS[shape].RIDGE   # runs across the support along v: its pitch along v is free
    pitch = layout["pitch_mm"]
    if ridge and not isinstance(pitch, list | tuple):
        pitch = [pitch, pitch]
    if not isinstance(pitch, list | tuple) or len(pitch) != 2:
        raise ElementError(f"layout.pitch_mm must be [pu, pv] in mm, got {pitch!r}"[:300])
    pu = _pitch(pitch[0], "layout.pitch_mm[0]", a)
    pv = number(pitch[1], "layout.pitch_mm[1]") if ridge else _pitch(pitch[1], "layout.pitch_mm[1]", a)
    return _model({**common, "layout": {"type": "grid", "pitch_mm": [pu, pv]}}, args, fx.GRID, (pu, pv), t0)


def _density(layout: dict, common: dict, args: tuple, t0: float) -> Microstructure:
    check_fields(layout, "layout", {"type", "origin_mm", "size_mm", "fill"}, {"seed", "pitch_mm", "placement"})
    a = args[1]
    u0, v0 = pair(layout["origin_mm"], "layout.origin_mm", lo=-math.inf)
    su, sv = pair(layout["size_mm"], "layout.size_mm")
    p = _pitch(layout.get("pitch_mm", 2.0 * a), "layout.pitch_mm", a)
    seed = layout.get("seed", 1)
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2 ** 63:
        raise ElementError(f"layout.seed must be an integer >= 0, got {seed!r}"[:300])
    placement = layout.get("placement", "blue_noise")
    if placement not in PLACEMENTS:
        raise ElementError(f"layout.placement must be one of {list(PLACEMENTS)} (blue_noise: error diffusion, the "
                           f"default; random: each site alone), got {placement!r}"[:300])
    fill = _fill(layout["fill"])
    nu, nv = int(su // p), int(sv // p)
    if nu * nv == 0:
        raise ElementError(f"layout.size_mm {[su, sv]} holds no site of pitch {p:g} mm: make it larger")
    _affordable(nu, nv, p, su, sv, placement)
    canon = {**common, "layout": {"type": "density", "origin_mm": [u0, v0], "size_mm": [su, sv],
                                  "fill": fill.tolist(), "seed": seed, "pitch_mm": p}}
    if placement == "blue_noise":   # a random layout's body (and id) is as it was before placements
        canon["layout"]["placement"] = placement
        bits = np.zeros((nu * nv + 7) // 8, np.uint8)
        kept_count = int(diffuse(fill, nu, nv, p, su, sv, seed, bits))
        return _model(canon, args, fx.DENSITY, (p, p), t0, origin=(u0, v0), cells=(nu, nv), bits=bits,
                      features=kept_count)
    rows, cols = fill.shape
    rng = np.random.default_rng(seed)
    # a band of sites at a time (row after row, along u), packed as drawn: a whole number of bytes per band, so the
    # bands' bytes join into the lattice's bits, and the same random stream whatever the band. Whole rows (a multiple
    # of 8) where 8 rows fit a band; else (rows of millions of sites) runs of sites across rows
    band = max(8, BAND_BYTES // BAND_SITE_BYTES // 8 * 8)
    sites = nu * nv
    bits = np.empty((sites + 7) // 8, np.uint8)
    kept_count = 0
    whole_rows = 8 * nu <= band
    step = band // nu // 8 * 8 * nu if whole_rows else band
    col_of = np.minimum(((np.arange(nu) + 0.5) * p / su * cols).astype(np.int64), cols - 1) if whole_rows else None
    for s0 in range(0, sites, step):
        s1 = min(sites, s0 + step)
        if col_of is not None:
            j = np.arange(s0 // nu, s1 // nu)
            row_of = np.minimum(((j + 0.5) * p / sv * rows).astype(np.int64), rows - 1)
            kept = (rng.random((len(j), nu)) < fill[row_of][:, col_of]).ravel()
        else:
            j, i = np.divmod(np.arange(s0, s1), nu)
            row_of = np.minimum(((j + 0.5) * p / sv * rows).astype(np.int64), rows - 1)
            kept = rng.random(len(i)) < fill[row_of, np.minimum(((i + 0.5) * p / su * cols).astype(np.int64),
                                                                cols - 1)]
        kept_count += int(np.count_nonzero(kept))
        packed = np.packbits(kept, bitorder="little")
        bits[s0 // 8:s0 // 8 + len(packed)] = packed
    return _model(canon, args, fx.DENSITY, (p, p), t0, origin=(u0, v0), cells=(nu, nv), bits=bits,
                  features=kept_count)


def density_cost(sites: int, placement: str = "random", row_sites: int = 0) -> tuple[float, float]:
    """(bytes, seconds) preparing a density lattice of `sites` sites, `row_sites` in a row, takes: its bits, and one
    band's temporaries (random) or the rows of carried error (blue noise); the sites at the placement's
    `SITES_PER_SECOND`. An estimate from the counts alone, made before any work."""
    temporaries = min(BAND_BYTES, BAND_SITE_BYTES * sites) if placement == "random" else 0
    return (sites * SITE_BYTES + temporaries + ROW_SITE_BYTES[placement] * row_sites,
            sites / SITES_PER_SECOND[placement])


def max_density_sites(placement: str = "blue_noise") -> int:
    """The most lattice sites one request may prepare with that placement (`MAX_PREPARE_BYTES`,
    `MAX_PREPARE_SECONDS`, `MAX_SITES`; a blue-noise lattice's rows count beside, in `_affordable`)."""
    return int(min(MAX_SITES, (MAX_PREPARE_BYTES - BAND_BYTES) / SITE_BYTES,
                   MAX_PREPARE_SECONDS * SITES_PER_SECOND[placement]))


def _affordable(nu: int, nv: int, p: float, su: float, sv: float, placement: str) -> None:
    """`ElementError` where a lattice of nu × nv sites would cost more than one request may (`density_cost`), saying
    what it would cost and what to change: the pitch it needs, or the size it may have, at the same fill."""
    sites = nu * nv
    limit = max_density_sites(placement)
    need, seconds = density_cost(sites, placement, nu)
    if sites <= limit and need <= MAX_PREPARE_BYTES:
        return
    grow = math.sqrt(max(sites / limit, need / MAX_PREPARE_BYTES))
    row = f", and {ROW_SITE_BYTES[placement]} bytes per site of a row" if ROW_SITE_BYTES[placement] else ""
    raise ElementError(
        f"layout: {nu} x {nv} = {sites:,} lattice sites would take about {need / 2 ** 20:,.0f} MiB and "
        f"{seconds:,.0f} s to prepare; one request prepares at most {limit:,} sites ({MAX_PREPARE_BYTES >> 20} MiB, "
        f"{MAX_PREPARE_SECONDS:g} s at {SITES_PER_SECOND[placement]:.2g} sites/s placed {placement}{row}): give a "
        f"coarser layout.pitch_mm (at least "
        f"{p * grow * 1.001:.4g} mm; the fill map keeps its meaning) or a smaller layout.size_mm (at most "
        f"{su / grow:.4g} x {sv / grow:.4g} mm at this pitch), or split the face into several elements")


def _fill(fill: Any) -> np.ndarray:
    try:
        f = np.array(fill, dtype=np.float64)
    except (TypeError, ValueError):
        raise ElementError("layout.fill must be rows of numbers in [0, 1] (a rectangular table)") from None
    if f.ndim != 2 or f.size == 0:
        raise ElementError(f"layout.fill must be a non-empty table (rows along v, columns along u), got shape "
                           f"{f.shape}")
    if f.size > MAX_MAP_CELLS:
        raise ElementError(f"layout.fill has {f.size} cells, more than {MAX_MAP_CELLS}")
    bad = np.argwhere(~((f >= 0.0) & (f <= 1.0)))
    if len(bad):
        r, c = (int(x) for x in bad[0])
        raise ElementError(f"layout.fill[{r}][{c}] = {float(f[r, c])!r} is outside [0, 1]: a fill is the fraction of "
                           f"lattice sites that hold a feature")
    return f


def _points(layout: dict, common: dict, args: tuple, t0: float) -> Microstructure:
    """Listed centres, checked for overlaps (a k-d tree: pairs closer than a feature's width) and binned by a grid of
    about one point per cell (a counting sort: `bins` starts, `items` ids), all in numpy: 12 bytes per point and
    4 per cell. The body keeps the list as given (no copy)."""
    check_fields(layout, "layout", {"type", "uv_mm"}, set())
    shape, a = args[0], args[1]
    uv = _uv_array(layout["uv_mm"])
    if len(uv) > MAX_POINTS:
        raise ElementError(f"layout.uv_mm lists {len(uv)} features, more than {MAX_POINTS}: use a density layout")
    if not np.isfinite(uv).all():
        raise ElementError(f"layout.uv_mm[{int(np.argwhere(~np.isfinite(uv))[0][0])}] is not finite")
    from scipy.spatial import cKDTree

    tree = cKDTree(uv, balanced_tree=False, compact_nodes=False)   # the faster build; queries as fast here
    pairs = tree.query_pairs(2.0 * a * (1.0 - 1e-9), p=2.0 if SHAPE_KINDS[shape].ROUND else np.inf,
                             output_type="ndarray")
    if len(pairs):
        i, j = (int(x) for x in pairs[0])
        raise ElementError(f"layout.uv_mm[{i}] and [{j}] overlap ({uv[i].tolist()} and {uv[j].tolist()} mm): keep "
                           f"centres at least {2 * a:g} mm apart")
    lo = uv.min(axis=0) - a
    span = uv.max(axis=0) + a - lo
    size = max(2.0 * a, math.sqrt(float(span[0] * span[1]) / len(uv)))
    nu, nv = (int(x) for x in np.maximum(1, np.ceil(span / size)))
    cu = np.minimum(((uv[:, 0] - lo[0]) // size).astype(np.int32), nu - 1)
    cv = np.minimum(((uv[:, 1] - lo[1]) // size).astype(np.int32), nv - 1)
    flat = cv.astype(np.int64) * nu + cu
    counts = np.bincount(flat, minlength=nu * nv)
    bins = np.zeros(nu * nv + 1, np.int32)
    np.cumsum(counts, out=bins[1:])
    items = np.argsort(flat, kind="stable").astype(np.int32)
    given = layout["uv_mm"]
    canon = {**common, "layout": {"type": "points", "uv_mm": given if isinstance(given, list) else uv.tolist()}}
    return _model(canon, args, fx.POINTS, (size, size), t0, origin=(float(lo[0]), float(lo[1])), cells=(nu, nv),
                  uv=uv.astype(np.float32), bins=bins, items=items, features=len(uv), uv64=uv)
