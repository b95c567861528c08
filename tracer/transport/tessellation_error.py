"""The tessellation error budget (docs/DESIGN.md, "Accuracy is a quantity"): how far a tessellated curved optical
surface may be from the true one, and how far that may move the illuminance an answer reports.

Contract
--------
Geometry, in the mesh's own units (`SurfaceError`):

- ``position``: a bound on the distance of any point of the mesh from the true surface (the sagitta);
- ``normal``: a bound on the angle (rad) between the normal the tracer reflects and refracts about and the true
  normal at the nearest surface point. Where the mesh has vertex normals (`cad_adapter.tessellate` writes the
  B-rep's own, exact at the vertices) the tracer uses the interpolated vertex normal (`tracer.optics.surfaces.base.
  specular_normal`), and that is what is bounded;
- ``curvature``: the largest normal curvature, 1/units (0 for a flat surface).

Two sources, both plain numpy (nothing here runs per photon):

- `from_settings(linear, angular, radius)`: from the deflections the mesh was made with (OCCT's
  ``BRepMesh_IncrementalMesh``; linear ``d`` in the mesh's units, angular ``a`` in rad) and the surface's smallest
  radius of curvature ``R``. OCCT refines until the chord–arc distance at the points it checks is at most ``d`` and
  the normals at neighbouring nodes differ by at most ``a``; a triangle spans two parametric directions, so its
  diagonal may turn the normal by √2·a, an arc of sagitta R(1 − cos(a/√2)). OCCT does not check every point of a
  triangle: measured on a cadquery sphere of radius 10, the mesh lies up to 2.08·d from it (d ≤ 0.01, triangles
  by the seam whose long edge OCCT left with a midpoint sagitta of 2.07·d), 1.3·d at d = 0.02, and under 0.8·d on
  a paraboloid (tests/tracer/transport/test_tessellation_error.py). So position ≤ `OCCT_EXCESS` · min(d, R(1 −
  cos(a/√2))) with OCCT_EXCESS = 2.5: an empirical constant with a margin over the 2.08 measured, not a proof. The
  normal spread over a triangle is ψ ≤ min(√2·a, 2·acos(1 − position/R)), and the normal error at most ψ (below).
- `from_mesh(vertices, triangles, normals)`: for a mesh pushed alone (no settings known), from its vertex normals.
  Per triangle, ψ is the largest angle between two of its vertex normals and ℓ its longest edge; an arc whose
  normal turns by ψ over a chord ℓ lies at most (ℓ/2)·tan(ψ/4) off the chord. Inside a triangle whose vertices lie
  on a sphere the largest distance is at the circumcentre, ρ²/2R (ρ the circumradius), against (ℓ/2)²/2R at the
  midpoint of the longest edge; ρ ≤ ℓ/√3 in an acute triangle (in an obtuse one the largest distance is on an
  edge), so the interior exceeds the edge by at most 4/3, and position ≤ max over triangles of
  4/3 · (ℓ/2) tan(ψ/4) ≈ ℓψ/6 (measured: 1.04× to 1.48× the true distance on the sphere and the paraboloid).
  The first candidate, θ = the angle between
  the facet normal and the vertex normals (sagitta ≈ ℓθ/4), was measured and dropped: on the thin triangles OCCT
  makes at a pole or an apex the facet normal of a float32 triangle is noise (θ = 1.9 rad on a 1.6e-4 mm² sliver
  at a paraboloid's apex, and 0.83 rad on a sphere where the true error is 0), while the vertex normals the
  tracer actually uses stay within ψ = 0.03 rad. The interpolated normal and the true normal both lie within the
  cone of the three vertex normals (the surface bends one way over a triangle), so normal ≤ ψ. That bound is first
  order and the interpolated normal's error second order: on the paraboloid it is 0.1–0.2 ψ², so ψ is 13× to 250×
  the measured error (and on a sphere the interpolated normal is exact: p/|p| at every point of a facet), which
  makes the illuminance budget below loose where the normal term dominates. A second-order bound needs the
  derivative of the curvature, which the mesh gives only noisily; not done. Curvature: the largest angle between
  the two end normals of an edge over its length.

Both are bounds of the same quantity; where both are known the smaller one holds.

Illuminance (`lux_budget`), lx per query point. A photon that meets the tessellated surface instead of the true
one meets it up to position/cos(i) further along its path (i ≤ 60° assumed: ≤ 2·position) and turns about a normal
that is off by up to normal + curvature·2·position (the normal error, and the true normal's own change over that
displacement). Reflection doubles an angle error; refraction turns the ray by less than the normal's tilt when it
enters glass and by (n cos i / cos t − 1) × tilt when it leaves it, at most 2× except within a few degrees of
total internal reflection, so 2× is taken for both. A photon therefore lands, at a distance L from the surface, at
most Δ = m · (2·position + 2·(normal + 2·curvature·position)·L) from where the true surface would have sent it,
with m the interactions per passage (1 for a mirror, 2 for a solid of glass: in and out) and L the largest
distance from the receiver to the surface's bounding box. Moving every photon by at most Δ changes the flux into a
receiver only through those landing within Δ of its rim: for a disk of radius r a band of area
π((r + Δ)² − max(r − Δ, 0)²), for a w × h cell (w + 2Δ)(h + 2Δ) − max(w − 2Δ, 0)·max(h − 2Δ, 0). Taking the
illuminance over that band to be the receiver's own |E| (the field varies little over Δ near the rim: stated,
not proven; at a focus smaller than the receiver the band is darker and the bound loose), the value may move by

    budget = |E| × band area / receiver area.

All the light at the point is treated as having met the surface (conservative where some did not). Several curved
surfaces add their Δ. The Fresnel split (reflect or refract) also changes with the angle; that second-order term
is left out.

Measured (tests/tracer/transport/test_tessellation_error.py, a paraboloid mirror of focal length 0.25 m and rim 0.5 m
under a collimated beam, disks of radius 5 cm, 400k photons): at the focus the coarse dish (linear 1 cm, angular 0.5)
gives 71,554 ± 37 lx against 81,000 through the fine one (0.5 mm, 0.05), a gap of 9,446 lx, and a budget of
6.8e6 lx; beyond the focus gaps of 6.5 and 8.5 lx (within noise) against budgets of 7.3e4 and 7.1e4. The budget
holds and is loose by two orders of magnitude: Δ ≈ 0.34 m against a 5 cm receiver, almost all of it the
first-order normal term 2ψL (ψ = 0.26 rad where the interpolated normal is off by ~0.01).

The estimate (`refine`, `extrapolate`, `Simulation.run(..., tessellation_estimate=True)`; issue 42). The bound
above is thousands of times the error: too loose to say whether to re-tessellate. The estimate measures instead: the
same query (same seed and stop rules) on the curved meshes split 1→4, twice or three times, and extrapolates the
sequence E_0, E_1, E_2 (, E_3) to the limit of the splits.

- What a split converges to. The service has no B-rep (docs/DESIGN.md: it runs without the CAD stack), so the finer
  surface comes from the mesh itself: its positions and its vertex normals, which `cad_adapter.tessellate` takes
  from the B-rep (exact at the vertices). A split whose new vertices only approximate the surface converges to a
  surface of its own. The first `refine` (PN triangles: Phong-lifted midpoints, quadratic-normal midpoint normals)
  did: on the paraboloid the midpoint normal n_a + n_b is off by O(h²) (the unit normals' average is not the
  normal where |∇z| changes along the edge), as large as the interpolated normal's own error, so the mean normal
  error fell only 1.12× to 1.19× a split and the refined values stayed near the coarse one: at the bench's focus
  disk the estimate was 0.059× the error. Now each new vertex is the point above the edge's midpoint of a quartic
  height field fitted (weighted least squares, 3 equations a point: height and slopes) to the positions and normals
  of both ends' `RING` nearest neighbours, with the fit's normal: off by O(h⁵) in position and O(h⁴) in normal,
  far below the O(h²) of what it replaces. A quartic, not a cubic: on the bench's 16 mm mesh (194 triangles) the
  new vertices' mean normal error is 0.13 mrad against 0.37 for a cubic (max 0.43 against 2.1), their mean
  distance from the surface 1 µm against 37 µm. Measured on the coarse dish (572 triangles): the mean error of
  the interpolated normal falls 0.75 → 0.18 → 0.044 mrad (4.1×, 4.2×) and the largest distance from the surface
  2.5 → 0.64 → 0.16 mm
  (tests/tracer/transport/test_tessellation_error.py). Where the fit lacks points (fewer than `FIT_MIN_POINTS` with
  a normal) or answers implausibly, the PN midpoint stands in.
- The observed order. The values converge like the geometry only once the blur the facets make is small next to
  the receiver; before that (a 0.5 mm disk at a focus under a 16 mm mesh) they change faster at each split than at
  the one before. So the ratio r = |E_L − E_(L−1)| / |E_(L−1) − E_(L−2)| is measured, not assumed (Richardson with
  the observed order: r = 2^−p), and a third split runs where some value is not yet in the asymptotic range
  (`converged`: r ≤ ½ or the last difference within 2σ). r is clipped to [0, R_MAX = ½]: the slowest convergence
  credited is first order in h (the geometry converges at second order; a value converging slower is taken as
  first order, the tail then equal to the last difference); where the differences change sign, or the earlier one
  is noise, r = ½ as well.
- The estimate: SAFETY · (|E_L − E_0| + |E_L − E_(L−1)| · r/(1 − r)), the distance from the coarse value to the
  extrapolated limit (the tail's size added whatever its sign). SAFETY = 1.25 is Roache's factor for a grid
  convergence index from three or more grids with the observed order (Roache, "Quantification of uncertainty in
  computational fluid dynamics", Annu. Rev. Fluid Mech. 29, 1997; ASME V&V 20): the published margin for an
  extrapolated error estimate, not fitted here. Its standard error takes the levels as independent (they share the
  seed, so their differences are less noisy than that: conservative).
- What it cost: the refinements and 2–3 more runs of the query (a split quadruples the triangles; the tracing time
  grows little with them, a BVH), stated in the answer (``tessellation_estimate_seconds``).

It is an estimate, not a bound. Measured (issue 42's aim: between the true error and 10× it, or within 5 % of the
value of it): on the coarse dish with a point source at its focus (572 triangles, 7 receivers 3 m up, truth a
6,360-triangle mesh, 2M photons) it meets the aim at every point: 1.22× to 1.43× the error at the six points where
that exceeds 3σ (4 % to 10 % of the value; the bound there 6,400× to 20,000×), 0.7× at the seventh where the
error is 0.4σ; on that fine mesh it is at most 2.0 % of the value (tests/tracer/transport/test_tessellation_error.py;
cost 4.0 s with 3 splits beside a 0.8 s query, 5.3 s with 2 splits of the fine mesh); at the bench's focus disk
(0.5 mm, collimated beam) it is 1.25× to 1.61× the error at all nine tolerances, 16 mm to 0.0625 mm, errors 97 %
down to 0.003 % (bench/bench_accuracy.py section (b), bench/results/REPORT.md), where the earlier one-split
difference gave 0.059×. Cost there: 2.5 s (3 splits of 194 triangles) to 21 s (2 splits of 44,583: building and
tracing 0.7 million triangles) beside a 1 s query.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

INTERIOR = 4.0 / 3.0          # a triangle's interior sagitta over its edges' (sphere, circumcentre argument)
OCCT_EXCESS = 2.5             # OCCT's mesh distance over its linear deflection: 2.08 measured (module docstring)
INCIDENCE_FACTOR = 2.0        # 1 / cos(60°): the path excess over a sagitta at the largest incidence assumed
TURN_FACTOR = 2.0             # ray turn per normal error: exact for reflection, refraction away from TIR
FLAT = 1e-6                   # rad: a mesh whose vertex normals spread less than this is flat (float32 noise)


@dataclass(frozen=True)
class SurfaceError:
    """Bounds on a tessellation's error (mesh units; see the module docstring).

    position : float — distance of the mesh from the true surface; normal : float, rad — error of the normal the
    tracer uses; curvature : float, 1/units — largest normal curvature.
    """

    position: float
    normal: float
    curvature: float

    @property
    def curved(self) -> bool:
        return self.curvature > 0.0 and self.normal > FLAT

    def tighter(self, other: SurfaceError) -> SurfaceError:
        """Both bound the same mesh: the smaller of each (curvature: the larger estimate, it is not a bound)."""
        return SurfaceError(min(self.position, other.position), min(self.normal, other.normal),
                            max(self.curvature, other.curvature))



def from_settings(linear: float, angular: float, radius: float) -> SurfaceError:
    """Bounds from OCCT's deflections: linear ``d`` (mesh units), angular ``a`` (rad) and the surface's smallest
    radius of curvature ``radius`` (mesh units; inf for a flat one). See the module docstring for the derivation."""
    for name, v in (("linear", linear), ("angular", angular), ("radius", radius)):
        if not v > 0:
            raise ValueError(f"{name} must be > 0, got {v!r}")
    if math.isinf(radius):
        return SurfaceError(0.0, 0.0, 0.0)
    position = OCCT_EXCESS * min(linear, radius * (1.0 - math.cos(angular / math.sqrt(2.0))))
    spread = min(math.sqrt(2.0) * angular, 2.0 * math.acos(max(-1.0, 1.0 - position / radius)))
    return SurfaceError(position, spread, 1.0 / radius)


def _angles(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angles between unit vectors (…, 3), accurate for small ones (atan2 of |a×b| and a·b)."""
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))


def from_mesh(vertices, triangles, normals) -> SurfaceError:
    """Bounds from a mesh's vertex normals (a mesh pushed alone). vertices (n, 3), triangles (m, 3) int,
    normals (n, 3) (any length; zero rows are ignored). See the module docstring for the derivation."""
    v = np.asarray(vertices, np.float64)
    t = np.asarray(triangles, np.int64)
    n = np.asarray(normals, np.float64)
    if v.ndim != 2 or v.shape[1] != 3 or n.shape != v.shape or t.ndim != 2 or t.shape[1] != 3:
        raise ValueError(f"expected vertices (n, 3), normals (n, 3), triangles (m, 3); got {v.shape}, {n.shape}, "
                         f"{t.shape}")
    if len(t) == 0:
        return SurfaceError(0.0, 0.0, 0.0)
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.where(ln > 0, n / np.where(ln > 0, ln, 1.0), 0.0)
    nt, pt = n[t], v[t]                                        # (m, 3, 3)
    ok = np.all(np.linalg.norm(nt, axis=2) > 0.5, axis=1)      # triangles with three usable normals
    if not ok.any():
        return SurfaceError(0.0, 0.0, 0.0)
    nt, pt = nt[ok], pt[ok]
    nxt = [1, 2, 0]
    spread_e = _angles(nt, nt[:, nxt])                          # (m, 3): the angle across each edge
    length_e = np.linalg.norm(pt - pt[:, nxt], axis=2)
    spread = spread_e.max(axis=1)                               # ψ per triangle
    longest = length_e.max(axis=1)
    position = float(np.max(INTERIOR * 0.5 * longest * np.tan(spread / 4.0)))
    with np.errstate(divide="ignore", invalid="ignore"):
        kappa = np.where(length_e > 0, spread_e / np.where(length_e > 0, length_e, 1.0), 0.0)
    normal = float(spread.max())
    if normal <= FLAT:
        return SurfaceError(0.0, 0.0, 0.0)
    return SurfaceError(position, normal, float(kappa.max()))


def shift(err: SurfaceError, distance, interactions: int = 1) -> np.ndarray:
    """Δ: how far a photon may land from where the true surface would send it, at `distance` (any shape, world
    units) from the surface; `err` in world units. See the module docstring."""
    L = np.asarray(distance, np.float64)
    tilt = err.normal + err.curvature * INCIDENCE_FACTOR * err.position
    return interactions * (INCIDENCE_FACTOR * err.position + TURN_FACTOR * tilt * L)


def rim_fraction(delta, radius: float | None = None, cell: tuple[float, float] | None = None) -> np.ndarray:
    """The area within `delta` (any shape) of a receiver's rim over the receiver's area: a disk of `radius`, or a
    rectangular `cell` (w, h)."""
    d = np.asarray(delta, np.float64)
    if (radius is None) == (cell is None):
        raise ValueError("give a disk radius or a cell (w, h), one of them")
    if radius is not None:
        r = float(radius)
        return ((r + d) ** 2 - np.maximum(r - d, 0.0) ** 2) / (r * r)
    w, h = (float(x) for x in cell)  # type: ignore[union-attr]
    return ((w + 2 * d) * (h + 2 * d) - np.maximum(w - 2 * d, 0.0) * np.maximum(h - 2 * d, 0.0)) / (w * h)


@dataclass(frozen=True)
class CurvedSurface:
    """A curved optical surface in the scene: its error in world units, its world bounding box (2, 3) and the
    interactions a photon has with it per passage (1 mirror, 2 glass solid)."""

    error: SurfaceError
    bounds: np.ndarray
    interactions: int
    instance: int = -1


def farthest(points: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """Largest distance from each point (k, 3) to the box `bounds` (2, 3): to its farthest corner."""
    b = np.asarray(bounds, np.float64)
    p = np.asarray(points, np.float64)
    far = np.maximum(np.abs(p - b[0]), np.abs(p - b[1]))
    return np.linalg.norm(far, axis=-1)


def lux_budget(lux, points, surfaces: Sequence[CurvedSurface], radius: float | None = None,
               cell: tuple[float, float] | None = None) -> np.ndarray:
    """How far each value may move when the curved surfaces are tessellated finely enough, lx.

    lux : (k,) the answer's values; points : (k, 3) receiver centres (world); surfaces : the scene's curved
    optical surfaces; radius (disk receivers) or cell (w, h) (a grid's cells), world units. Returns (k,) ≥ 0.
    """
    e = np.abs(np.asarray(lux, np.float64)).ravel()
    p = np.asarray(points, np.float64).reshape(-1, 3)
    delta = np.zeros(len(p))
    for s in surfaces:
        delta += shift(s.error, farthest(p, s.bounds), s.interactions)
    return e * rim_fraction(delta, radius=radius, cell=cell)


def scene_surfaces(scene, spec_of: dict, instances) -> list[CurvedSurface]:
    """The curved optical surfaces of a committed `tracer.Scene`: instances whose material reflects specularly
    (effect ``specular``: one interaction per passage) or refracts (``fresnel``: a solid, two) and whose mesh has
    vertex normals that spread (`from_mesh`). spec_of : {instance id: material spec}; instances : the ids to look
    at. Errors in world units: the mesh's scaled by the instance transform's largest singular value (its
    curvature by the smallest)."""
    from tracer.optics.surfaces.dispatch import effects_of

    per_geometry: dict[str, SurfaceError] = {}
    out = []
    for i in instances:
        spec = spec_of.get(i)
        if spec is None:
            continue
        fx = effects_of([spec])
        interactions = 2 if "fresnel" in fx else 1 if "specular" in fx else 0
        if not interactions:
            continue
        gid = scene.instance_geometry(i)
        if gid not in per_geometry:
            v, t, n = scene.geometry_arrays(gid)
            per_geometry[gid] = SurfaceError(0.0, 0.0, 0.0) if n is None else from_mesh(v, t, n)
        err = per_geometry[gid]
        if not err.curved:
            continue
        sv = np.linalg.svd(scene.instance_transform(i)[:3, :3], compute_uv=False)
        world = SurfaceError(err.position * float(sv[0]), err.normal,
                             err.curvature / float(sv[-1]) if sv[-1] > 0 else math.inf)
        out.append(CurvedSurface(world, scene.instance_bounds(i), interactions, int(i)))
    return out


def grid_cells(origin, u, v, nu: int, nv: int) -> tuple[np.ndarray, tuple[float, float]]:
    """Centres (nv·nu, 3), row j = v-cell j as a grid's lux, and the (w, h) of the cells of origin + s u + t v."""
    o, uu, vv = (np.asarray(x, np.float64) for x in (origin, u, v))
    jj, ii = np.divmod(np.arange(nu * nv), nu)
    centres = o + ((ii + 0.5) / nu)[:, None] * uu + ((jj + 0.5) / nv)[:, None] * vv
    return centres, (float(np.linalg.norm(uu)) / nu, float(np.linalg.norm(vv)) / nv)


# ------------------------------------------------------------------------------------------------ the estimate

SAFETY = 1.25     # Roache's grid convergence index: the factor on a Richardson estimate from three or more grids
R_MAX = 0.5       # the slowest convergence per split credited: first order in h (the geometry converges at 2nd)
MIN_LEVELS, MAX_LEVELS = 2, 3
MAX_TRIANGLES = 3_000_000   # a further split is not made past this many triangles in the refined curved meshes
ESTIMATE_METHOD = ("the same query (same seed and stop rules) on the curved meshes split 1→4 along the surface "
                   "their positions and vertex normals describe (`refine`), twice or three times; the observed "
                   "ratio r of successive differences (clipped to [0, ½]) extrapolates them (Richardson with the "
                   "observed order) and estimate = 1.25·(|E_L − E_0| + |E_L − E_(L−1)|·r/(1 − r)) (Roache's grid "
                   "convergence index); an estimate, not a bound")


def extrapolate(lux, stderr) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The tessellation error of level 0 from the same query on levels 0 … L of `refine` (L ≥ 2).

    lux, stderr : (L + 1, k) values and their Monte Carlo standard errors, level 0 the mesh as given. Returns
    (estimate (k,), its standard error (k,), r (k,) the convergence ratio used). See the module docstring."""
    e = np.asarray(lux, np.float64)
    s = np.asarray(stderr, np.float64)
    if e.ndim != 2 or e.shape != s.shape or len(e) < 3:
        raise ValueError(f"expected lux and stderr (L + 1, k) with L >= 2, got {e.shape} and {s.shape}")
    prev, last = e[-2] - e[-3], e[-1] - e[-2]
    resolved = np.abs(prev) > 2.0 * np.hypot(s[-2], s[-3])       # the earlier difference is not noise
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(resolved & (prev * last >= 0), np.abs(last) / np.where(resolved, np.abs(prev), 1.0), R_MAX)
    r = np.clip(r, 0.0, R_MAX)
    tail = r / (1.0 - r)
    estimate = SAFETY * (np.abs(e[-1] - e[0]) + np.abs(last) * tail)
    se = SAFETY * np.sqrt(s[0] ** 2 + s[-1] ** 2 + tail ** 2 * (s[-1] ** 2 + s[-2] ** 2))
    return estimate, se, r


def converged(lux, stderr) -> bool:
    """Whether levels 0 … L (L ≥ 2) need no further split: at every value the last difference is at most half the
    one before (the asymptotic range, r ≤ R_MAX) or within two standard errors of noise."""
    e = np.asarray(lux, np.float64)
    s = np.asarray(stderr, np.float64)
    prev, last = np.abs(e[-2] - e[-3]), np.abs(e[-1] - e[-2])
    return bool(np.all((last <= R_MAX * prev) | (last <= 2.0 * np.hypot(s[-1], s[-2]))))


RING = 8           # neighbours per vertex a midpoint's surface fit takes (the nearest; a pole's fan has dozens)
JET = [(k - j, j) for k in range(5) for j in range(k + 1)]   # the quartic's monomials u^i w^j: 1, u, w, u², …
FIT_MIN_POINTS = 6  # distinct points with a normal the quartic needs (3 equations each, 15 unknowns): else PN


def _unit(x: np.ndarray) -> np.ndarray:
    length = np.linalg.norm(x, axis=-1, keepdims=True)
    return np.where(length > 1e-300, x / np.where(length > 1e-300, length, 1.0), 0.0)


def _rings(v: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """(n, RING) the nearest neighbours of each vertex along the mesh's edges (unique (e, 2)), −1 padded."""
    pairs = np.concatenate([edges, edges[:, ::-1]])
    order = np.lexsort((np.linalg.norm(v[pairs[:, 1]] - v[pairs[:, 0]], axis=1), pairs[:, 0]))
    pairs = pairs[order]
    start = np.searchsorted(pairs[:, 0], np.arange(len(v)))
    rank = np.arange(len(pairs)) - start[pairs[:, 0]]
    keep = rank < RING
    ring = np.full((len(v), RING), -1, np.int64)
    ring[pairs[keep, 0], rank[keep]] = pairs[keep, 1]
    return ring


def _fit_midpoints(v: np.ndarray, n: np.ndarray, a: np.ndarray, b: np.ndarray, ring: np.ndarray,
                   chunk: int = 8192) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The surface point and normal over each edge's chord midpoint, from a quartic height field fitted by weighted
    least squares to the positions AND normals of the two ends' rings (a local jet fit). Returns (points (e, 3),
    normals (e, 3), ok (e,) bool: False where too few points have a usable normal, or the fit is implausible)."""
    mid_p = np.zeros((len(a), 3))
    mid_n = np.zeros((len(a), 3))
    good = np.zeros(len(a), bool)
    for s in range(0, len(a), chunk):
        aa, bb = a[s:s + chunk], b[s:s + chunk]
        pts = np.concatenate([aa[:, None], bb[:, None], ring[aa], ring[bb]], axis=1)   # (E, 2 + 2·RING)
        valid = pts >= 0
        pts = np.where(valid, pts, 0)
        m = 0.5 * (v[aa] + v[bb])
        e = v[bb] - v[aa]
        L = np.linalg.norm(e, axis=1)
        L = np.where(L > 0, L, 1.0)
        z = _unit(n[aa] + n[bb])                                            # the frame: height along z
        x = _unit(e - np.sum(e * z, 1, keepdims=True) * z)
        y = np.cross(z, x)
        d = (v[pts] - m[:, None]) / L[:, None, None]                        # in edge lengths
        u, w, h = (np.sum(d * q[:, None], -1) for q in (x, y, z))
        nn = n[pts]
        nu, nw, nz = (np.sum(nn * q[:, None], -1) for q in (x, y, z))
        ok = valid & (nz > 0.3)                                            # a normal the height field can take
        safe = np.where(ok, nz, 1.0)
        gu, gw = np.where(ok, -nu / safe, 0.0), np.where(ok, -nw / safe, 0.0)
        rows = np.concatenate([np.stack([u ** i * w ** j for i, j in JET], -1),                    # h
                               np.stack([i * u ** max(i - 1, 0) * w ** j for i, j in JET], -1),    # ∂h/∂u
                               np.stack([j * u ** i * w ** max(j - 1, 0) for i, j in JET], -1)], 1)  # ∂h/∂w
        rhs = np.concatenate([h, gu, gw], 1)
        wt = np.where(ok, 1.0 / (1.0 + u * u + w * w) ** 2, 0.0)            # nearer points weigh more
        W = np.concatenate([wt, wt, wt], 1)
        ata = np.einsum("epi,ep,epj->eij", rows, W, rows) + 1e-12 * np.eye(len(JET))
        atb = np.einsum("epi,ep,ep->ei", rows, W, rhs)
        c = np.linalg.solve(ata, atb[..., None])[..., 0]
        srt = np.sort(np.where(ok, pts, -1), axis=1)
        distinct = np.sum((srt[:, 1:] != srt[:, :-1]) & (srt[:, 1:] >= 0), axis=1) + (srt[:, 0] >= 0)
        nrm = _unit(z - c[:, 1:2] * x - c[:, 2:3] * y)                   # JET: 1, u, w first
        mid_p[s:s + chunk] = m + (c[:, 0] * L)[:, None] * z
        mid_n[s:s + chunk] = nrm
        good[s:s + chunk] = ((distinct >= FIT_MIN_POINTS) & np.all(np.isfinite(c), axis=1)
                             & (np.abs(c[:, 0]) < 0.5) & (np.sum(nrm * z, 1) > 0.5))
    return mid_p, mid_n, good


def refine(vertices, triangles, normals) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Split every triangle into four at its edge midpoints, each midpoint put on the surface the mesh's positions
    and vertex normals describe, with that surface's normal there (`_fit_midpoints`: a quartic height field over the
    edge's frame fitted to the positions and normals of both ends' `RING` nearest neighbours; the midpoint's
    position is then off by O(h⁵) and its normal by O(h⁴), far below the O(h²) of the interpolated normal it
    replaces, so repeated splits converge to the true surface; see the module docstring). Where the fit has too
    few points with a usable normal, or answers implausibly (height over half the edge, normal over 60° from the
    ends'), the midpoint falls back to PN triangles: m − ¼ Σ_end ((m − p)·n) n (Phong tessellation with α = ½),
    normal n_a + n_b + h with h the normalised n_a + n_b reflected in the plane normal to the edge. A vertex
    without a usable normal (zero row) leaves its edges straight. Returns (vertices, triangles, normals),
    float64/int64."""
    v = np.asarray(vertices, np.float64)
    t = np.asarray(triangles, np.int64)
    n = np.asarray(normals, np.float64)
    if v.ndim != 2 or v.shape[1] != 3 or n.shape != v.shape or t.ndim != 2 or t.shape[1] != 3:
        raise ValueError(f"expected vertices (n, 3), normals (n, 3), triangles (m, 3); got {v.shape}, {n.shape}, "
                         f"{t.shape}")
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.where(ln > 0, n / np.where(ln > 0, ln, 1.0), 0.0)
    edges = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    key = np.sort(edges, axis=1)
    uniq, inv = np.unique(key, axis=0, return_inverse=True)
    inv = inv.ravel()
    a, b = uniq[:, 0], uniq[:, 1]
    m = 0.5 * (v[a] + v[b])
    lift = 0.25 * (np.sum((m - v[a]) * n[a], axis=1, keepdims=True) * n[a]
                   + np.sum((m - v[b]) * n[b], axis=1, keepdims=True) * n[b])
    e = v[b] - v[a]
    ee = np.sum(e * e, axis=1, keepdims=True)
    ns = n[a] + n[b]
    with np.errstate(divide="ignore", invalid="ignore"):
        h = ns - np.where(ee > 0, 2.0 * np.sum(e * ns, axis=1, keepdims=True) / np.where(ee > 0, ee, 1.0), 0.0) * e
    lh = np.linalg.norm(h, axis=1, keepdims=True)
    h = np.where(lh > 1e-12, h / np.where(lh > 1e-12, lh, 1.0), 0.0)
    mn = ns + h                                                 # PN triangles' quadratic normal at the midpoint
    lm = np.linalg.norm(mn, axis=1, keepdims=True)
    mn = np.where(lm > 1e-12, mn / np.where(lm > 1e-12, lm, 1.0), 0.0)
    pm = m - lift
    fp, fn, good = _fit_midpoints(v, n, a, b, _rings(v, uniq))
    good &= (np.linalg.norm(n[a], axis=1) > 0.5) & (np.linalg.norm(n[b], axis=1) > 0.5)
    pm = np.where(good[:, None], fp, pm)
    mn = np.where(good[:, None], fn, mn)
    mid = len(v) + inv.reshape(3, -1)                           # (3, m): midpoint of edge 01, 12, 20
    m01, m12, m20 = mid
    t0, t1, t2 = t[:, 0], t[:, 1], t[:, 2]
    tri = np.concatenate([np.stack([t0, m01, m20], 1), np.stack([m01, t1, m12], 1),
                          np.stack([m20, m12, t2], 1), np.stack([m01, m12, m20], 1)])
    return np.concatenate([v, pm]), tri, np.concatenate([n, mn])
