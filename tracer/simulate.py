"""The illuminance query: `Simulation` (docs/CONTRACTS.md, "light transport → service").

A `Simulation` holds a committed `tracer.Scene`, the material of every instance, and the lights, all
validated once. Its queries:

- `illuminance(points, normals, radius=...)`: the illuminance (lx) on the front side of a small disk
  receiver (radius `radius`, default `DEFAULT_RADIUS`) at each point, averaged over the disk;
- `grid(origin, u, v, nu, nv)`: the illuminance averaged over each cell of a rectangle
  origin + s u + t v (front side u × v), as an (nv, nu) map;
- `surface(instances)`: the illuminance on the model itself, per triangle of each instance listed: the
  luminous flux arriving on the triangle's front side (the side its geometric normal points to, object-space
  e1 × e2 mapped to world: the outside of a CAD solid; light arriving from behind is not counted) divided by
  its world area (the instance's transform applied), averaged over the triangle. Forward only: the kernel
  adds each photon's weight where it hits a tallied triangle, before the surface scatters it
  (`tracer.transport.SensorArrays.surf`), which observes and changes nothing: every path and every other
  tally of the same query is bit-identical with and without it. Its error stop looks at every triangle
  (one that received nothing so far counts as converged), so a target error on a fine mesh is reached late:
  give it a photon or time budget.
- `far_field(nc, ngamma, direction, c0)`: the luminous intensity (cd) of the whole scene as a lamp, on a type-C
  grid (γ from `direction`, C from `c0`, as a goniometric light's; `tracer.photometry`): every photon that leaves
  the scene (its ray meets nothing) is binned by its direction, I = flux in the bin / the bin's solid angle. A far
  field: the scene is taken as a point, small against the viewing distance (a photometric distance of five or more
  times the luminaire's largest dimension, the usual rule): where the lamp is seen from nearer, its size matters and
  this answer does not hold. Forward only; it observes and changes nothing (`tracer.transport.SensorArrays.far`).

Both estimators estimate exactly these patch averages, so they agree within their error bars:

- ``"forward"`` (`tracer.transport`): photons from the sources, recorded by the query's own receivers:
  sensor instances (`Scene.add_disk_sensor` / `add_rect_sensor`) in a small scene of their own beside
  the scene, which a query only reads (so queries on one scene may run at once, and nobody copies it);
- ``"backward"`` (`tracer.backward`): paths from uniform points of each patch with next-event
  estimation; only where every surface is purely diffuse (its kind says so) and every light can be
  reached by a shadow ray (its kind says so). ``"auto"`` takes it for `illuminance` where it applies,
  and forward otherwise and for grids; the result says which ran.

A query point may lie exactly on a surface (a receiver on the floor). The mesh is stored in float32,
so the surface the rays meet may lie a little above or below the point given. `place_receivers`
therefore probes along the normal from `probe_distance(p)` (1e-6 m + 2⁻²⁰ × the coordinate
magnitude, 16 float32 ulps) above the point down to as far below it; where it meets a surface, the
receiver is put on the surface the rays actually meet. In every case it then sits `sensor_offset`
in front: max(1e-9 m, 2⁻⁴⁴ × the coordinate magnitude), 5.7e-9 m at 1e5 m from the origin, ~400
float64 ulps there — far above the error of the crossing distances (computed in object space, where
an instance's translation has cancelled), so light arriving at the floor crosses the receiver
before it hits the floor, and far too small to change the answer. Where the facet met is tilted
against the receiver by float32 rounding (≲ 1e-7 rad on a tessellated sphere), the receiver is moved
a further 2 r sin(tilt), so that no part of the disk lies behind the facet. Light leaving the floor crosses
the receiver from behind (spawned rays start 2⁻³² × magnitude off the surface) and is not counted.

Estimation: independent batches seeded from (seed, batch index) through the counter-based
`tracer.rng`; batch sizes depend only on the request and the backend's `tracer.backends.BatchShape`, batches are
started in rounds of `ROUND_BATCHES`, growing to a quarter of the batches run so far (at most `MAX_ROUND_BATCHES`,
and `MAX_ROUND_BYTES` of tallies: a long query gives a cluster's workers tasks of 0.1 s or more while a stop
overshoots its rule by at most a quarter; a GPU's shape has thousands of small batches a round), and the
stop test runs between rounds, so for the same seed and stop rule (target error or photon budget) the answer is
bit-identical whatever the number of threads, processes or machines the batches of one shape ran on. Standard errors
are batch means (`tracer.estimate`). A query stops when every point's relative error is at most
`target_relative_error` (``"target_relative_error"``), at `max_photons` (``"max_photons"``),
`max_seconds` (``"max_seconds"``) or when `cancel()` is truthy (``"cancelled"``). Without any
budget it runs `DEFAULT_MAX_SECONDS`. Every answer has at least two batches (an error bar needs two),
so a photon budget below two batches' worth (`max_photons: 1`) runs two batches of the smallest size.
A patch that received nothing in every batch so far counts as converged (0 ± 0): a point in full
shadow does not hold a query to its time budget, but a forward query for a very small receiver far
from the light can stop at 0 early; give it a photon budget.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tracer.accel.traverse import closest_each
from tracer.backends import CPU_SHAPE, IN_PROCESS, InProcess, Shipment, is_backend
from tracer.backward import QueryArrays, disk_queries
from tracer.effects import EFFECTS, EffectError, derive_effects, photon_state, with_forced
from tracer.errors import TracerError
from tracer.estimate import Estimate, cost_of
from tracer.gpu.device import DeviceUnavailable
from tracer.optics import spectra
from tracer.optics.lights import connectable, pack_lights
from tracer.optics.lights.dispatch import polarized_lights, spectral_lights
from tracer.optics.surfaces.dispatch import backward_ok, material_spec, pack_materials
from tracer.scene import Scene
from tracer.tessellation_error import grid_cells, lux_budget, scene_surfaces
from tracer.transport import COUNTERS, SensorArrays, tally_columns
from tracer.warmup import wait_background

DEFAULT_RADIUS = 0.05          # m: disk receiver radius when the query gives none
DEFAULT_MAX_SECONDS = 30.0     # s: budget of a query that states none
# the CPU's cut of a query (`tracer.backends.BatchShape`; a backend may cut it otherwise: `backend.shape`)
ROUND_BATCHES = CPU_SHAPE.first_round        # batches started between two stop tests (the first rounds)
MAX_ROUND_BATCHES = CPU_SHAPE.max_round      # the largest round, however long the query has run
FORWARD_BATCH = CPU_SHAPE.forward_photons    # photons per forward batch (fewer when max_photons is small)
BACKWARD_BATCH = CPU_SHAPE.backward_paths    # paths per patch per backward batch
MIN_BATCHES = 8                # batches before the error bar is trusted for a target-error stop
MAX_ROUND_BYTES = 256 << 20    # a round's tallies (batches × bins × 8 B) stay below this: fewer batches a round
ESTIMATORS = ("auto", "forward", "backward")
OBSERVABLES = ("spectrum", "stokes")
MAX_SPECTRAL_TALLIES = 4_000_000   # bins × spectral columns a query may record per batch

log = logging.getLogger(__name__)
_COMPILE_SECONDS: dict[tuple, float] = {}   # first call of each compiled variant in this process


class SimulationError(TracerError):
    """A query or a scene the transport cannot simulate; the message says why."""


@dataclass
class IlluminanceResult:
    """Illuminance at query points.

    lux, stderr : (k,) float64, lx — patch-average illuminance and its standard error.
    photons : int — photons (forward) or paths (backward, all points together) traced.
    seconds : float — wall time of the query.
    effects : list[str] — the effect set of the kernel that ran.
    estimator : "forward" or "backward".
    stop_reason : "target_relative_error", "max_photons", "max_seconds" or "cancelled".
    batches : int; rejected : int — samples dropped as non-finite (never tallied);
    counters : dict — every kernel counter; compile_seconds : float — spent compiling (or loading
    from numba's cache) a kernel variant used for the first time in this process.
    Where the query observes the spectrum: nm (N_BINS,) — centres of the 5 nm bands;
    spectral_irradiance, spectral_stderr (k, N_BINS) — W/m²/nm in each band and its standard error;
    cie_xy (k, 2) — CIE 1931 chromaticity of the light arriving (NaN where nothing arrived).
    cost : dict — what tighter errors would cost on this scene and machine (`tracer.estimate.cost_of`).
    error_budget : dict or None — ``{"tessellation": (k,) lx}`` where the scene holds curved optical surfaces
    (mirror or glass meshes with vertex normals): how far each value may move when they are tessellated finely
    enough (`tracer.tessellation_error`); None elsewhere.
    backend : dict — where the batches ran (`tracer.backends`): {"name": "in-process", "threads": n} or
    {"name": "dask", "address": …, "workers": n, "threads": n}.
    physics_left_out : dict or None — where the query asked (`Simulation.left_out`): per effect,
    ``{"difference": (k,) lx, "stderr": (k,) lx, "photons", "seconds", "estimator", "ran"}``, the lux with that
    effect forced on minus `lux`.
    Where the query observes Stokes (`tracer.optics.polarization`): stokes, stokes_stderr (k, 4) — lx, S0 = lux,
    in each receiver's frame (x axis: its `reference` in its plane, taken across each photon's direction);
    dop (k,) — degree of polarization √(S1² + S2² + S3²) / S0 (NaN where nothing arrived).
    """

    lux: np.ndarray
    stderr: np.ndarray
    photons: int
    seconds: float
    effects: list[str]
    estimator: str
    stop_reason: str
    batches: int = 0
    rejected: int = 0
    counters: dict = field(default_factory=dict)
    compile_seconds: float = 0.0
    nm: np.ndarray | None = None
    spectral_irradiance: np.ndarray | None = None
    spectral_stderr: np.ndarray | None = None
    cie_xy: np.ndarray | None = None
    stokes: np.ndarray | None = None
    stokes_stderr: np.ndarray | None = None
    dop: np.ndarray | None = None
    cost: dict | None = None
    error_budget: dict | None = None
    backend: dict | None = None
    physics_left_out: dict | None = None


@dataclass
class GridResult(IlluminanceResult):
    """Illuminance of a grid sensor: `lux` and `stderr` have shape (nv, nu); row j is v-cell j."""


@dataclass
class FarFieldResult:
    """Luminous intensity of the scene as a lamp (`Simulation.far_field`).

    candela, stderr : (nγ, nc) float64, cd — row j is γ_j = j Δγ (Δγ = 180°/(nγ−1)), column i is C_i = i ΔC
    (ΔC = 360°/nc); each the flux leaving the scene in the bin's directions (γ in [γ_j − Δγ/2, γ_j + Δγ/2] within
    [0°, 180°], C in [C_i − ΔC/2, C_i + ΔC/2)) divided by the bin's solid angle, and its standard error (batch
    means). The polar caps (rows 0 and nγ−1) are one bin each: every column holds the cap's value.
    c_deg (nc,), gamma_deg (nγ,) : the sample angles, degrees. solid_angle (nγ, nc) : sr of each bin (a cap's
    whole solid angle in each of its columns). flux_lm, flux_stderr : the total flux leaving the scene, lm, and its
    standard error. direction, c0 : (3,) the frame's γ = 0 axis and C = 0 axis (unit; c0 taken across direction).
    The other fields as for `IlluminanceResult` (estimator is always "forward").
    """

    candela: np.ndarray
    stderr: np.ndarray
    c_deg: np.ndarray
    gamma_deg: np.ndarray
    solid_angle: np.ndarray
    flux_lm: float
    flux_stderr: float
    direction: np.ndarray
    c0: np.ndarray
    photons: int
    seconds: float
    effects: list[str]
    estimator: str
    stop_reason: str
    batches: int = 0
    rejected: int = 0
    counters: dict = field(default_factory=dict)
    compile_seconds: float = 0.0
    backend: dict | None = None


def far_field_bins(nc: int, ngamma: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The C-γ grid of a far field (`FarFieldResult`): c_deg (nc,), gamma_deg (nγ,), solid angle (nγ, nc) sr."""
    c_deg = np.arange(nc) * (360.0 / nc)
    gamma_deg = np.arange(ngamma) * (180.0 / (ngamma - 1))
    half = 90.0 / (ngamma - 1)
    lo = np.radians(np.clip(gamma_deg - half, 0.0, 180.0))
    hi = np.radians(np.clip(gamma_deg + half, 0.0, 180.0))
    band = np.cos(lo) - np.cos(hi)
    omega = np.tile((band * (2.0 * math.pi / nc))[:, None], (1, nc))
    omega[0, :] = omega[-1, :] = 2.0 * math.pi * band[0]
    return c_deg, gamma_deg, omega


@dataclass
class SurfaceResult:
    """Illuminance on the triangles of instances (`Simulation.surface`).

    instances : list[int] — the instances asked for, in order; lux, stderr, area : list of (m_i,) float64 per
    instance, in the order of its geometry's triangles — lx on each triangle's front side, its standard error
    (batch means), the triangle's world area (m²; a degenerate triangle reads 0 ± 0). The other fields as for
    `IlluminanceResult` (estimator is always "forward").
    """

    instances: list[int]
    lux: list[np.ndarray]
    stderr: list[np.ndarray]
    area: list[np.ndarray]
    photons: int
    seconds: float
    effects: list[str]
    estimator: str
    stop_reason: str
    batches: int = 0
    rejected: int = 0
    counters: dict = field(default_factory=dict)
    compile_seconds: float = 0.0
    backend: dict | None = None


def sensor_offset(p: np.ndarray) -> float:
    """How far a query patch is moved off its plane along its normal, m (see the module docstring)."""
    return max(1e-9, 2.0 ** -44 * float(np.max(np.abs(p))))


def probe_distance(p: np.ndarray) -> float:
    """How far from a query point a surface is taken to be the one it lies on, m (16 float32 ulps)."""
    return 1e-6 + 2.0 ** -20 * float(np.max(np.abs(p)))


def place_receivers(sa, points: np.ndarray, normals: np.ndarray, radius: float) -> np.ndarray:
    """Receiver centres (k, 3): each point moved onto the surface it lies on (if any, within
    `probe_distance`) and then in front of it along its unit normal (see the module docstring).

    The offset is `sensor_offset`, plus, where the surface met is tilted against the receiver by less
    than 1e-3 rad (float32 rounding of a facet the point lies on), 2 r sin(tilt), so that the whole
    disk of radius r stays in front of the facet the rays meet.
    """
    wait_background("probe")
    k = len(points)
    h = np.array([probe_distance(p) for p in points])
    origins = np.ascontiguousarray(points + h[:, None] * normals)
    hit_t, hit_inst, hit_normal = np.empty(k), np.empty(k, np.int64), np.empty((k, 3))
    closest_each(sa, origins, np.ascontiguousarray(-normals), np.full(k, np.inf), hit_t, hit_inst, hit_normal)
    out = np.empty_like(points)
    for i in range(k):
        base = points[i]
        extra = 0.0
        if hit_inst[i] >= 0 and hit_t[i] <= 2.0 * h[i]:
            base = origins[i] - hit_t[i] * normals[i]
            sin_tilt = float(np.linalg.norm(np.cross(hit_normal[i], normals[i])))
            if sin_tilt < 1e-3:
                extra = 2.0 * radius * sin_tilt
        out[i] = base + (sensor_offset(base) + extra) * normals[i]
    return out


def _vectors(a, name: str, k: int | None = None) -> np.ndarray:
    try:
        v = np.asarray(a, dtype=np.float64)
    except (TypeError, ValueError):
        raise SimulationError(f"{name} must be numbers, shape (k, 3)") from None
    if v.ndim == 1 and v.shape == (3,) and k is None:
        v = v[None, :]
    if v.ndim != 2 or v.shape[1] != 3:
        raise SimulationError(f"{name} must have shape (k, 3), got {v.shape}")
    if k is not None and v.shape[0] != k:
        raise SimulationError(f"{name} has {v.shape[0]} rows, expected {k}")
    if not np.all(np.isfinite(v)):
        raise SimulationError(f"{name} must be finite")
    return v


def _vec3(a, name: str) -> np.ndarray:
    try:
        v = np.asarray(a, dtype=np.float64)
    except (TypeError, ValueError):
        raise SimulationError(f"{name} must be 3 numbers") from None
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise SimulationError(f"{name} must be 3 finite numbers, got {a!r}")
    return v


@dataclass
class _Budget:
    target: float | None
    max_seconds: float | None
    max_photons: int | None
    scope: str = "worst"


TARGET_SCOPES = ("worst", "lit", "mean")
LIT_FRACTION = 0.01   # "lit" values: at least this fraction of the brightest one


def _budget(target_relative_error, max_seconds, max_photons, scope="worst") -> _Budget:
    if target_relative_error is not None:
        if isinstance(target_relative_error, bool) or not (0 < float(target_relative_error) < 1):
            raise SimulationError(f"target_relative_error must be in (0, 1), got {target_relative_error!r}")
        target_relative_error = float(target_relative_error)
    if max_seconds is not None:
        if isinstance(max_seconds, bool) or not (0 < float(max_seconds) < math.inf):
            raise SimulationError(f"max_seconds must be > 0 and finite, got {max_seconds!r}")
        max_seconds = float(max_seconds)
    if max_photons is not None:
        if isinstance(max_photons, bool) or int(max_photons) != max_photons or int(max_photons) < 1:
            raise SimulationError(f"max_photons must be a positive integer, got {max_photons!r}")
        max_photons = int(max_photons)
    if scope not in TARGET_SCOPES:
        raise SimulationError(f"target_scope must be one of {list(TARGET_SCOPES)}, got {scope!r}")
    if target_relative_error is None and max_seconds is None and max_photons is None:
        max_seconds = DEFAULT_MAX_SECONDS
    return _Budget(target_relative_error, max_seconds, max_photons, scope)


def _stop_error(est: Estimate, mean_est: Estimate, n_stop: int | None, scope: str) -> float:
    """The relative error a target is held to (`target_scope`): "worst", the largest over the values;
    "lit", the largest over the values at least `LIT_FRACTION` of the brightest (cells in shadow, which
    a handful of stray photons reach, cannot hold a grid to its target); "mean", that of the mean of
    the values (its batch means, `mean_est`)."""
    if scope == "mean":
        return float(mean_est.relative_error()[0])
    rel = est.relative_error()[:n_stop]
    if scope == "lit" and rel.size:
        mean = est.mean[:n_stop]
        top = float(np.max(mean))
        rel = rel[mean >= LIT_FRACTION * top] if top > 0 else rel[:0]
    return float(np.max(rel)) if rel.size else 0.0


class Simulation:
    """Light transport over one committed scene (docs/CONTRACTS.md).

    Parameters
    ----------
    scene : tracer.Scene
        Committed. Queries add their receivers as sensor instances for their duration (under a
        lock: queries of one `Simulation` run one at a time on the scene).
    materials : {instance id: material body}
        DESIGN.md material bodies, or their typed specs (`tracer.optics.surfaces`).
    lights : list of light bodies
        World metres (`tracer.optics.lights`); area lights carry ``"instances"``.
    default_material : material body, optional
        For instances not in `materials`; without it every non-sensor instance needs a material.
    backend : `tracer.backends.InProcess`, `DaskBackend` or `tracer.gpu.backend.CudaBackend`, optional
        Where the batches run; default this process's threads. The answer is the same wherever they run (within
        error bars on a GPU). A query whose scene does not fit on the card runs on this process's threads, and its
        result's `backend` says why (``"fallback"``).

    Raises
    ------
    SimulationError, MaterialError, LightError (all ValueError)
        Saying which body or field is wrong.
    """

    def __init__(self, scene, materials: dict[int, dict], lights: list[dict], default_material: dict | None = None,
                 backend: Any = None):
        if scene is None or not hasattr(scene, "arrays"):
            raise SimulationError("scene must be a tracer.Scene")
        if getattr(scene, "dirty", False) is True:
            raise SimulationError("the scene has changes that are not committed: call scene.commit() first")
        if not isinstance(materials, dict):
            raise SimulationError(f"materials must be a dict {{instance id: body}}, got {type(materials).__name__}")
        if backend is not None and not is_backend(backend):
            raise SimulationError(f"backend must be a tracer.backends backend, got {type(backend).__name__}")
        self.backend = IN_PROCESS if backend is None else backend
        self._shipments: dict[str, Shipment] = {}   # the snapshot each kernel reads, per photon state
        self.scene = scene
        self._arrays = scene.arrays()   # the committed scene, read-only from here on
        ids = [int(i) for i in scene.instances()]
        self._sensor_ids = {i for i in ids if _is_sensor(scene, i)}
        mats = {}
        for key, body in materials.items():
            if isinstance(key, bool) or not isinstance(key, int | np.integer):
                raise SimulationError(f"materials: keys must be instance ids (int), got {key!r}")
            if int(key) not in self._sensor_ids:   # a sensor has no surface: nothing to assign
                mats[int(key)] = material_spec(body, f"material of instance {int(key)}")
        default_spec = material_spec(default_material, "default_material") if default_material is not None else None
        self._mats = pack_materials(mats, default_spec, ids, self._sensor_ids)
        self._lights = pack_lights(list(lights), scene, frozenset(self._sensor_ids))
        self._lights_spectral = spectral_lights(self._lights)   # the same lights for photons with a wavelength
        geometry_ids = [i for i in ids if i not in self._sensor_ids]
        # the distinct specs in use (a scene of 100k instances has a handful of materials)
        self._specs = list(dict.fromkeys(m for m in (mats.get(i, default_spec) for i in geometry_ids) if m is not None))
        self.effects: list[str] = derive_effects(self._specs, lights)   # the one rule, as the service's summary
        self._curved = scene_surfaces(scene, {i: mats.get(i, default_spec) for i in geometry_ids}, geometry_ids)

    # ------------------------------------------------------------------------------------------ helpers

    def backward_applies(self, effects: list[str] | None = None) -> tuple[bool, str]:
        """Whether the backward estimator can answer for this scene (and effect set), and if not why."""
        effects = self.effects if effects is None else effects
        if set(effects) - {"lambertian"}:
            return False, (f"the scene needs {sorted(set(effects) - {'lambertian'})}: point-like sources cannot be "
                           f"reached through specular or refractive surfaces by shadow rays")
        ok, why = backward_ok(self._specs)
        if not ok:
            return False, why
        return connectable(self._lights)

    def _choose(self, estimator: str, effects: list[str], grid: bool) -> str:
        if estimator not in ESTIMATORS:
            raise SimulationError(f"estimator must be one of {list(ESTIMATORS)}, got {estimator!r}")
        ok, why = self.backward_applies(effects)
        if estimator == "backward" and not ok:
            raise SimulationError(f"the backward estimator cannot answer here: {why}; use 'forward' or 'auto'")
        if estimator == "auto":
            return "backward" if (ok and not grid) else "forward"
        return estimator

    # ------------------------------------------------------------------------------------------ queries

    def illuminance(self, points, normals, radius=None, target_relative_error=None, max_seconds=None,
                    max_photons=None, seed=0, estimator="auto", force_effects=(), progress=None,
                    cancel=None, observe=(), reference=None, physics_left_out=(),
                    target_scope="worst") -> IlluminanceResult:
        """Illuminance (lx) on the front side of a disk receiver at each point.

        Parameters
        ----------
        points, normals : (k, 3) float
            Receiver centres (m) and front-side normals (any non-zero length).
        radius : float, optional
            Receiver radius, m (default `DEFAULT_RADIUS`).
        target_relative_error, max_seconds, max_photons : stop rules (see the module docstring).
        target_scope : which relative error the target holds: "worst" (every value's), "lit" (every value at
            least `LIT_FRACTION` of the brightest) or "mean" (the mean of the values').
        seed : int ≥ 0.
        estimator : "auto", "forward" or "backward".
        force_effects : effect names to compile in although the scene does not need them.
        progress : callable(photons, worst_relative_error, seconds), called once before the first round (0
            photons: `seconds` is what compiling or loading the kernel took) and between rounds.
        cancel : callable() -> bool, polled between rounds.
        observe : ("spectrum",) to add the spectral irradiance and the chromaticity (`IlluminanceResult`);
            photons then carry a wavelength (effect `spectral`), and the forward estimator answers. "stokes" adds
            the Stokes vector and the degree of polarization (effect `polarization`).
        reference : (3,) float, optional
            The x axis of the receivers' polarization frames (world), taken onto each receiver's plane; default
            world x, or world y where x is within 25° of the receiver's normal.
        physics_left_out : effect names (`tracer.effects.EFFECTS`) whose share of the answer to measure: the result's
            `physics_left_out` (`left_out`).
        """
        left_out = _left_out_names(physics_left_out)
        pts = _vectors(points, "points")
        k = len(pts)
        if k == 0:
            raise SimulationError("points must hold at least one point")
        nrm = _vectors(normals, "normals", k)
        ln = np.linalg.norm(nrm, axis=1)
        if np.any(ln <= 0):
            raise SimulationError(f"normal {int(np.argmax(ln <= 0))} is the zero vector")
        nrm = nrm / ln[:, None]
        r = DEFAULT_RADIUS if radius is None else radius
        if isinstance(r, bool) or not isinstance(r, int | float) or not (0 < r < math.inf):
            raise SimulationError(f"radius must be a positive finite number of metres, got {radius!r}")
        r = float(r)
        centers = place_receivers(self._arrays, pts, nrm, r)
        res = self._run(False, centers, nrm, r, None, target_relative_error, max_seconds, max_photons, seed,
                        estimator, force_effects, progress, cancel, observe, reference, target_scope=target_scope)
        if left_out:
            res.physics_left_out = self.left_out(left_out, res, lambda force, s, est: self._run(
                False, centers, nrm, r, None, target_relative_error, max_seconds, max_photons, s, est, force, None,
                cancel, (), target_scope=target_scope), force_effects, observe, seed, estimator)
        return res

    def grid(self, origin, u, v, nu, nv, target_relative_error=None, max_seconds=None, max_photons=None, seed=0,
             estimator="auto", force_effects=(), progress=None, cancel=None, observe=(), reference=None,
             physics_left_out=(), target_scope="worst") -> GridResult:
        """Cell-average illuminance (lx) over a grid sensor origin + s u + t v, front side u × v.

        Returns a `GridResult` whose `lux` and `stderr` are (nv, nu) arrays (observed spectra and
        chromaticities (nv, nu, …)). Other parameters as for `illuminance`.
        """
        left_out = _left_out_names(physics_left_out)
        o, uu, vv = _vec3(origin, "origin"), _vec3(u, "u"), _vec3(v, "v")
        for name, val in (("nu", nu), ("nv", nv)):
            if isinstance(val, bool) or not isinstance(val, int | np.integer) or not 1 <= val <= 4096:
                raise SimulationError(f"{name} must be an integer in [1, 4096], got {val!r}")
        nrm = np.cross(uu, vv)
        ln = float(np.linalg.norm(nrm))
        if not ln > 1e-12 * float(np.linalg.norm(uu) * np.linalg.norm(vv)) or ln == 0.0:
            raise SimulationError("u and v must be non-zero and not parallel")
        nrm = nrm / ln
        centre = o + 0.5 * (uu + vv)
        half_diagonal = 0.5 * float(np.linalg.norm(uu + vv))
        o = o + (place_receivers(self._arrays, centre[None, :], nrm[None, :], half_diagonal)[0] - centre) @ nrm * nrm
        res = self._run(True, o, nrm, 0.0, (uu, vv, int(nu), int(nv)), target_relative_error, max_seconds,
                        max_photons, seed, estimator, force_effects, progress, cancel, observe, reference,
                        target_scope=target_scope)
        shape = (int(nv), int(nu))

        def cells(a):
            return None if a is None else a.reshape(shape + a.shape[1:])

        out = GridResult(cells(res.lux), cells(res.stderr), res.photons, res.seconds, res.effects, res.estimator,
                         res.stop_reason, res.batches, res.rejected, res.counters, res.compile_seconds, res.nm,
                         cells(res.spectral_irradiance), cells(res.spectral_stderr), cells(res.cie_xy),
                         cells(res.stokes), cells(res.stokes_stderr), cells(res.dop), res.cost, backend=res.backend)
        if res.error_budget is not None:
            out.error_budget = {name: cells(v) for name, v in res.error_budget.items()}
        if left_out:
            found = self.left_out(left_out, res, lambda force, s, est: self._run(
                True, o, nrm, 0.0, (uu, vv, int(nu), int(nv)), target_relative_error, max_seconds, max_photons, s,
                est, force, None, cancel, (), target_scope=target_scope), force_effects, observe, seed, estimator)
            out.physics_left_out = {name: {**e, "difference": cells(e["difference"]), "stderr": cells(e["stderr"])}
                                    for name, e in found.items()}
        return out

    def surface(self, instances, target_relative_error=None, max_seconds=None, max_photons=None, seed=0,
                force_effects=(), progress=None, cancel=None) -> SurfaceResult:
        """Per-triangle illuminance (lx) on the front side of each instance in `instances` (see the module
        docstring), with its standard error; budget options as for `illuminance`. Forward only."""
        if isinstance(instances, str | bytes) or not hasattr(instances, "__iter__"):
            raise SimulationError(f"instances must be a list of instance ids, got {instances!r}")
        ids: list[int] = []
        for i in instances:
            if isinstance(i, bool) or not isinstance(i, int | np.integer):
                raise SimulationError(f"instances: ids must be ints, got {i!r}")
            if int(i) in ids:
                raise SimulationError(f"instances: {int(i)} is listed twice")
            ids.append(int(i))
        if not ids:
            raise SimulationError("instances: at least one instance is needed")
        known = {int(i) for i in self.scene.instances()}
        n_inst = max(known) + 1 if known else 0
        surf = np.full(max(n_inst, max(ids) + 1), -1, np.int64)
        areas = []
        base = 0
        for i in ids:
            if i not in known:
                raise SimulationError(f"instances: {i} is not an instance of the scene")
            if i in self._sensor_ids:
                raise SimulationError(f"instances: {i} is a sensor, it has no surface to tally")
            verts, tris, _ = self.scene.geometry_arrays(self.scene.instance_geometry(i))
            m = np.asarray(self.scene.instance_transform(i), np.float64)[:3, :3]
            w = np.asarray(verts, np.float64) @ m.T
            t = np.asarray(tris, np.int64)
            a = 0.5 * np.linalg.norm(np.cross(w[t[:, 1]] - w[t[:, 0]], w[t[:, 2]] - w[t[:, 0]]), axis=1)
            surf[i] = base
            base += len(a)
            areas.append(a)
        if base > MAX_SPECTRAL_TALLIES:
            raise SimulationError(f"the instances hold {base} triangles: at most {MAX_SPECTRAL_TALLIES} are tallied")
        res = self._run(False, np.empty((0, 3)), np.empty((0, 3)), 0.0, None, target_relative_error, max_seconds,
                        max_photons, seed, "forward", force_effects, progress, cancel, (),
                        surface=(surf, np.concatenate(areas)))
        lux, err, out_a = [], [], []
        at = 0
        for a in areas:
            lux.append(res.lux[at:at + len(a)])
            err.append(res.stderr[at:at + len(a)])
            out_a.append(a)
            at += len(a)
        return SurfaceResult(ids, lux, err, out_a, res.photons, res.seconds, res.effects, res.estimator,
                             res.stop_reason, res.batches, res.rejected, res.counters, res.compile_seconds,
                             res.backend)

    def far_field(self, nc, ngamma, direction=(0.0, 0.0, -1.0), c0=None, target_relative_error=None,
                  max_seconds=None, max_photons=None, seed=0, force_effects=(), progress=None,
                  cancel=None) -> FarFieldResult:
        """Luminous intensity (cd) of the whole scene seen from far away, on a type-C grid of `nc` C samples
        (ΔC = 360°/nc) and `ngamma` γ samples (Δγ = 180°/(ngamma−1)): `FarFieldResult`, with the total flux leaving
        the scene. γ is measured from `direction` (default −z, the nadir), C from `c0` (default +x, +y where
        `direction` lies along x; only its part across `direction` counts), C = 90° along c0 × direction, as for a
        goniometric light. The scene is taken as
        a point: valid where it is small against the viewing distance (see the module docstring). Budget options
        as for `illuminance`; the error stop looks at every bin (an empty one counts as converged). Forward only."""
        for name, val, lo, hi in (("nc", nc, 1, 3600), ("ngamma", ngamma, 2, 1801)):
            if isinstance(val, bool) or not isinstance(val, int | np.integer) or not lo <= val <= hi:
                raise SimulationError(f"{name} must be an integer in [{lo}, {hi}], got {val!r}")
        nc, ngamma = int(nc), int(ngamma)
        if nc * ngamma > MAX_SPECTRAL_TALLIES:
            raise SimulationError(f"nc × ngamma = {nc * ngamma} bins: at most {MAX_SPECTRAL_TALLIES}")
        axis = _vec3(direction, "direction")
        given = c0 is not None
        t = _vec3(c0 if given else (1.0, 0.0, 0.0), "c0")
        if not np.linalg.norm(axis) > 0:
            raise SimulationError("direction must not be the zero vector")
        axis = axis / np.linalg.norm(axis)
        t = t - axis * float(t @ axis)
        if not given and not np.linalg.norm(t) > 1e-9:
            t = np.array([0.0, 1.0, 0.0]) - axis * axis[1]
        if not np.linalg.norm(t) > 1e-9 * max(1.0, float(np.linalg.norm(c0 if given else t))):
            raise SimulationError(f"c0 {list(map(float, c0))} must not be parallel to direction "
                                  f"{list(map(float, direction))}")
        t = t / np.linalg.norm(t)
        b = np.cross(t, axis)   # C = 90°: c0 × direction (+y for the defaults)
        c_deg, gamma_deg, omega = far_field_bins(nc, ngamma)
        res = self._run(False, np.empty((0, 3)), np.empty((0, 3)), 0.0, None, target_relative_error, max_seconds,
                        max_photons, seed, "forward", force_effects, progress, cancel, (),
                        far=((nc, ngamma, *axis, *t, *b), omega.ravel()))
        cd = res.lux[:-1].reshape(ngamma, nc).copy()
        err = res.stderr[:-1].reshape(ngamma, nc).copy()
        for j in (0, ngamma - 1):   # a polar cap is one bin, tallied in its C = 0 column
            cd[j, :] = cd[j, 0]
            err[j, :] = err[j, 0]
        return FarFieldResult(cd, err, c_deg, gamma_deg, omega, float(res.lux[-1]), float(res.stderr[-1]), axis, t,
                              res.photons, res.seconds, res.effects, res.estimator, res.stop_reason, res.batches,
                              res.rejected, res.counters, res.compile_seconds, res.backend)

    # ------------------------------------------------------------------------------------------ physics left out

    def left_out(self, names: tuple[str, ...], res: IlluminanceResult, rerun, force_effects, observe, seed: int,
                 estimator: str) -> dict:
        """What each effect in `names` would change (DESIGN.md, "Accuracy is a quantity"): per effect ``{"difference":
        lux with it forced on − res.lux, "stderr": √(σ_run² + σ_pilot²), "photons", "seconds", "estimator" of the
        pilot, "ran"}``.

        The pilot (`rerun(force_effects, seed, estimator)`) is the same query with the effect forced on, under the
        query's own stop rules (its target error, photon and time budget: the difference's error is then about √2
        times the run's own, and the answer takes up to 1 + len(names) times as long) and an independent seed
        (`_pilot_seed`: the two estimates are independent, so their variances add). An effect that leaves the photon
        state the same (`tracer.effects.photon_state`) changes nothing that runs: it is already on, or a branch on data
        that acts wherever the scene's materials call for it (Fresnel wherever there is a dielectric); its difference
        is exactly 0 ± 0 and no pilot runs (``"ran": false``). What a pilot can change today is therefore the light's
        state: polarization (polarized Fresnel instead of the s/p average) and a wavelength per photon (spectral and
        the effects that need it). A cancelled run runs no pilot (``{}``).
        """
        if res.stop_reason == "cancelled":
            return {}
        spectrum, stokes = _observe(observe)
        asked = (*(force_effects or ()), *(("spectral",) if spectrum else ()), *(("polarization",) if stokes else ()))
        base = with_forced(self.effects, asked)
        pilot_estimator = "forward" if estimator == "forward" else "auto"
        out = {}
        for k, name in enumerate(names):
            if photon_state(with_forced(base, name)) == photon_state(base):
                zero = np.zeros_like(res.lux)
                out[name] = {"difference": zero, "stderr": zero.copy(), "photons": 0, "seconds": 0.0,
                             "estimator": None, "ran": False}
                continue
            pilot = rerun((*asked, name), _pilot_seed(seed, k), pilot_estimator)
            out[name] = {"difference": pilot.lux - res.lux, "stderr": np.hypot(pilot.stderr, res.stderr),
                         "photons": int(pilot.photons), "seconds": float(pilot.seconds),
                         "estimator": pilot.estimator, "ran": True}
        return out

    # ------------------------------------------------------------------------------------------ engine

    def _run(self, is_grid, centers, normals, radius, grid, target, max_seconds, max_photons, seed, estimator,
             force_effects, progress, cancel, observe, reference=None, surface=None, far=None,
             target_scope="worst") -> IlluminanceResult:
        """One query. `surface` = (surf, areas) adds the surface tally (`SensorArrays.surf`, bins after the
        receivers', their lux and stderr after the receivers' in the result; forward only). `far` = (params, solid
        angles) adds the far-field tally (`SensorArrays.far`) after those: cd, then the total flux leaving (lm)."""
        budget = _budget(target, max_seconds, max_photons, target_scope)
        observe_spectrum, observe_stokes = _observe(observe)
        if observe_spectrum:
            force_effects = (*(force_effects or ()), "spectral")
        if observe_stokes:
            force_effects = (*(force_effects or ()), "polarization")
        refs = _references(reference, np.atleast_2d(normals))
        if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or not 0 <= seed < 2 ** 63:
            raise SimulationError(f"seed must be an integer in [0, 2**63), got {seed!r}")
        if force_effects is None:
            force_effects = ()
        try:
            effects = with_forced(self.effects, force_effects)
        except EffectError as exc:
            raise SimulationError(f"{exc} (in force_effects)") from None
        which = self._choose(estimator, effects, is_grid)
        if (surface is not None or far is not None) and which != "forward":
            raise SimulationError("the surface and far-field tallies are forward only")
        if which == "backward":
            effects = ["lambertian"]
        t0 = time.perf_counter()
        backend = _QueryBackend(self.backend)
        if which == "forward":
            res = self._forward(is_grid, centers, normals, radius, grid, budget, int(seed), effects, progress,
                                cancel, t0, observe_spectrum, refs if observe_stokes else None, surface, far, backend)
        else:
            res = self._backward(is_grid, centers, normals, radius, grid, budget, int(seed), effects, progress,
                                 cancel, t0, backend)
        res.cost = cost_of(res.lux, res.stderr, res.photons, res.seconds - res.compile_seconds)
        if self._curved and surface is None and far is None:
            if is_grid:
                cell_centres, cell = grid_cells(centers, *grid)
                budget_lux = lux_budget(res.lux, cell_centres, self._curved, cell=cell)
            else:
                budget_lux = lux_budget(res.lux, centers, self._curved, radius=radius)
            res.error_budget = {"tessellation": budget_lux}
        res.backend = backend.describe()
        return res

    def _snapshot(self, state: str) -> Shipment:
        """The read-only scene a kernel takes (arrays, materials, lights packed for the photon state), one
        `Shipment` per state for the life of this simulation: sent to a cluster's workers once."""
        if state not in self._shipments:
            lights = self._lights_spectral if state.endswith("spectral") else self._lights
            if state.startswith("polarized"):
                lights = polarized_lights(lights)
            self._shipments[state] = Shipment((self._arrays, self._mats, lights))
        return self._shipments[state]

    def _warm(self, kernel_id: tuple, scene: Shipment, query: Shipment, backend: _QueryBackend) -> float:
        """Compile (or load from cache) a kernel where it runs, on a one-photon batch; seconds it took, once per
        process and backend (waiting for a child process that compiles it, `tracer.warmup`, included)."""
        local = isinstance(backend.backend, InProcess)
        variant = kernel_id if local else (backend.backend.name, *kernel_id)
        if variant in _COMPILE_SECONDS:
            return 0.0
        t = time.perf_counter()
        if local:
            wait_background(kernel_id[0])
        backend.run(kernel_id, scene, query, 0, 1, 1)
        if backend.fallback is not None:   # it compiled for this process's CPU, not where it was asked
            variant = kernel_id
        _COMPILE_SECONDS.setdefault(variant, time.perf_counter() - t)
        return _COMPILE_SECONDS[variant]

    def _loop(self, run_round, n_bins, per_batch, budget, progress, cancel, t0, shape, n_stop=None):
        """Rounds of batches until a stop rule holds; returns (Estimate, batches, stop_reason, counters).
        The error stop looks at the first `n_stop` bins (all by default): the illuminances, not the spectra.
        Rounds follow the backend's `shape`, and hold at most `MAX_ROUND_BYTES` of tallies."""
        max_round = max(2, min(shape.max_round, MAX_ROUND_BYTES // (8 * max(1, n_bins))))
        if progress is not None:   # before the first round: no photons yet, the seconds spent getting ready
            progress(0, math.inf, time.perf_counter() - t0)   # (compiling or loading the kernel, packing)
        est = Estimate.empty(n_bins)
        mean_est = Estimate.empty(1)   # the batch means of the values' mean (target_scope "mean")
        batches = 0
        counters = None
        while True:
            nb = min(max_round, max(shape.first_round, batches // 4))
            if budget.max_photons is not None:
                nb = min(nb, max(1, (budget.max_photons - batches * per_batch) // per_batch))
            nb = max(nb, 2 - batches)   # an error bar needs two batches, whatever the budget
            values, cnt = run_round(batches, nb)
            est.add(values)
            if budget.scope == "mean":
                mean_est.add(values[:, :n_stop].mean(axis=1, keepdims=True))
            counters = cnt.sum(axis=0) if counters is None else counters + cnt.sum(axis=0)
            batches += nb
            elapsed = time.perf_counter() - t0
            worst = _stop_error(est, mean_est, n_stop, budget.scope)
            if progress is not None:
                progress(batches * per_batch, worst, elapsed)
            if cancel is not None and cancel():
                return est, batches, "cancelled", counters
            if budget.target is not None and batches >= MIN_BATCHES and worst <= budget.target:
                return est, batches, "target_relative_error", counters
            if budget.max_photons is not None and (batches + 1) * per_batch > budget.max_photons:
                return est, batches, "max_photons", counters
            if budget.max_seconds is not None and elapsed >= budget.max_seconds:
                return est, batches, "max_seconds", counters

    def _forward(self, is_grid, centers, normals, radius, grid, budget, seed, effects, progress, cancel, t0,
                 observe_spectrum, refs, surface=None, far=None, backend=None):
        backend = backend or _QueryBackend(self.backend)
        receivers = Scene()
        ids: list[int] = []
        if is_grid:
            uu, vv, nu, nv = grid
            ids = [receivers.add_rect_sensor(centers, uu, vv)]
            n_bins = nu * nv
            area = np.full(n_bins, float(np.linalg.norm(np.cross(uu, vv))) / (nu * nv))
        else:
            ids = [receivers.add_disk_sensor(c, n, radius) for c, n in zip(centers, normals, strict=True)]
            n_bins = len(centers)
            area = np.full(n_bins, math.pi * radius * radius)
        receivers.commit()
        ra = receivers.arrays()
        bin0 = np.full(max(ids) + 1 if ids else 0, -1, np.int64)
        snu = np.ones(len(bin0), np.int64)
        snv = np.ones(len(bin0), np.int64)
        if is_grid:
            bin0[ids[0]] = 0
            snu[ids[0]], snv[ids[0]] = grid[2], grid[3]
        else:
            bin0[ids] = np.arange(len(ids))
        ref = np.zeros((len(bin0), 3))
        if refs is not None:
            ref[ids] = refs[:len(ids)]
        observe_stokes = refs is not None
        n_stop = n_bins   # the error stop: the receivers, or the triangles where there are none
        surf = np.empty(0, np.int64)
        if surface is not None:
            surf_map, surf_area = surface
            surf = np.where(surf_map >= 0, surf_map + n_bins, -1).astype(np.int64)
            n_bins += len(surf_area)
            area = np.concatenate([area, surf_area])
            n_stop = n_stop or n_bins
        far_row = np.empty(0, np.float64)
        if far is not None:
            far_params, far_omega = far
            far_row = np.array([n_bins, *far_params], np.float64)
            n_bins += len(far_omega) + 1
            area = np.concatenate([area, far_omega, [1.0]])   # cd; the last bin, the total leaving, in lm
            n_stop = n_stop or n_bins - 1
        sens = SensorArrays(bin0, snu, snv, np.array([int(observe_spectrum), int(observe_stokes)], np.int64), ref,
                            surf, far_row)
        n_cols = tally_columns(observe_spectrum, observe_stokes)
        if n_bins * n_cols > MAX_SPECTRAL_TALLIES:
            what = " and ".join(o for o, on in (("the spectrum", observe_spectrum), ("Stokes", observe_stokes)) if on)
            raise SimulationError(f"observing {what} of {n_bins} cells needs {n_bins * n_cols} tallies per "
                                  f"batch (at most {MAX_SPECTRAL_TALLIES}): use at most "
                                  f"{MAX_SPECTRAL_TALLIES // n_cols} cells")
        shape = backend.shape
        per_batch = shape.forward_photons
        if budget.max_photons is not None:
            per_batch = int(min(shape.forward_photons, max(1, budget.max_photons // (4 * shape.first_round))))
        state = photon_state(effects)
        kernel_id = ("forward", state)
        scene, query = self._snapshot(state), Shipment((ra, sens, n_bins, seed))
        compile_s = self._warm(kernel_id, scene, query, backend)

        with np.errstate(divide="ignore"):
            per_area = np.tile(np.where(area > 0, 1.0 / area, 0.0), n_cols)   # a degenerate triangle: 0 ± 0

        def run_round(b0, nb):
            flux, cnt = backend.run(kernel_id, scene, query, b0, nb, per_batch)
            return flux * per_area[None, :], cnt

        est, batches, stop, counters = self._loop(run_round, n_bins * n_cols, per_batch, budget, progress, cancel, t0,
                                                  shape,
                                                  n_stop)
        cdict = {name: int(c) for name, c in zip(COUNTERS, counters, strict=True)}
        mean, err = est.mean.reshape(n_cols, n_bins), est.stderr.reshape(n_cols, n_bins)
        res = IlluminanceResult(mean[0], err[0], batches * per_batch, time.perf_counter() - t0, effects,
                                "forward", stop, batches, cdict["rejected"], cdict, compile_s)
        if observe_spectrum:
            res.nm = spectra.bin_centres()
            res.spectral_irradiance = mean[3:].T / spectra.BIN_NM
            res.spectral_stderr = err[3:].T / spectra.BIN_NM
            x, y, z = mean[1], mean[0] / spectra.KM, mean[2]
            total = x + y + z
            with np.errstate(divide="ignore", invalid="ignore"):
                res.cie_xy = np.where(total[:, None] > 0, np.stack([x, y], axis=1) / total[:, None], np.nan)
        if observe_stokes:
            res.stokes = np.concatenate([mean[:1], mean[-3:]]).T
            res.stokes_stderr = np.concatenate([err[:1], err[-3:]]).T
            with np.errstate(divide="ignore", invalid="ignore"):
                res.dop = np.where(mean[0] > 0, np.sqrt((mean[-3:] ** 2).sum(axis=0)) / mean[0], np.nan)
        return res

    def _backward(self, is_grid, centers, normals, radius, grid, budget, seed, effects, progress, cancel, t0,
                  backend):
        if is_grid:
            uu, vv, nu, nv = grid
            k = nu * nv
            jj, ii = np.divmod(np.arange(k), nu)
            o = centers[None, :] + (ii / nu)[:, None] * uu[None, :] + (jj / nv)[:, None] * vv[None, :]
            q = QueryArrays(np.ones(k, np.int64), o, np.tile(uu / nu, (k, 1)), np.tile(vv / nv, (k, 1)),
                            np.tile(normals, (k, 1)))
        else:
            q = disk_queries(centers, normals, radius)
            k = len(centers)
        shape = backend.shape
        paths = shape.backward_paths
        per_batch = paths * k
        if budget.max_photons is not None:
            paths = int(min(shape.backward_paths, max(1, budget.max_photons // (4 * shape.first_round * k))))
            per_batch = paths * k
        scene, query = self._snapshot("backward"), Shipment((q, seed))
        compile_s = self._warm(("backward",), scene, query, backend)

        def run_round(b0, nb):
            return backend.run(("backward",), scene, query, b0, nb, paths)

        est, batches, stop, counters = self._loop(run_round, k, per_batch, budget, progress, cancel, t0, shape)
        cdict = {"rejected": int(counters[0]), "truncated": int(counters[1])}
        return IlluminanceResult(est.mean, est.stderr, batches * per_batch, time.perf_counter() - t0, effects,
                                 "backward", stop, batches, cdict["rejected"], cdict, compile_s)


class _QueryBackend:
    """One query's backend: `backend`, then, once it says the card cannot take the query
    (`tracer.gpu.device.DeviceUnavailable`: a scene that does not fit), this process's CPU threads for the rest of
    the query; `describe()` then says so and why (``"fallback"``). The same batches, the same random numbers."""

    def __init__(self, backend: Any) -> None:
        self.backend = backend
        self.shape = backend.shape   # kept on the CPU too: the same batches
        self.fallback: str | None = None

    def run(self, kernel_id, scene, query, batch0, n_batches, size):
        if self.fallback is None:
            try:
                return self.backend.run(kernel_id, scene, query, batch0, n_batches, size)
            except DeviceUnavailable as exc:
                self.fallback = f"ran on the CPU because {exc}"
                log.warning("%s", self.fallback)
        return IN_PROCESS.run(kernel_id, scene, query, batch0, n_batches, size)

    def describe(self) -> dict[str, Any]:
        if self.fallback is None:
            return self.backend.describe()
        return {**IN_PROCESS.describe(), "fallback": self.fallback}


def _left_out_names(names) -> tuple[str, ...]:
    """A query's `physics_left_out`, checked: a list of distinct `tracer.effects.EFFECTS`; `SimulationError` else."""
    if names is None:
        return ()
    if isinstance(names, str) or not isinstance(names, list | tuple):
        raise SimulationError(f"physics_left_out must be a list of effects {list(EFFECTS)}, got {names!r}")
    unknown = [e for e in names if e not in EFFECTS]
    if unknown:
        raise SimulationError(f"physics_left_out: unknown effect(s) {unknown}; known: {list(EFFECTS)}")
    if len(set(names)) != len(names):
        raise SimulationError(f"physics_left_out lists each effect once, got {list(names)}")
    return tuple(names)


def _pilot_seed(seed: int, k: int) -> int:
    """The seed of the k-th pilot of a query with `seed`: a stream of its own (`tracer.rng` seeds by (seed, batch))."""
    return (int(seed) + (k + 1) * 0x9E3779B97F4A7C15) % 2 ** 63


def _observe(observe) -> tuple[bool, bool]:
    """Whether a query's `observe` list asks for the spectrum, and for Stokes; `SimulationError` for anything else."""
    if observe is None:
        return False, False
    if isinstance(observe, str) or not isinstance(observe, list | tuple):
        raise SimulationError(f"observe must be a list of observables {list(OBSERVABLES)}, got {observe!r}")
    unknown = [o for o in observe if o not in OBSERVABLES]
    if unknown:
        raise SimulationError(f"observe: unknown observable(s) {unknown}; known: {list(OBSERVABLES)}")
    return "spectrum" in observe, "stokes" in observe


def _references(reference, normals: np.ndarray) -> np.ndarray:
    """(k, 3) unit x axes of the receivers' polarization frames: `reference` (default world x, world y where x is
    within 25° of the normal) taken onto each receiver's plane (unit normals (k, 3))."""
    if reference is None:
        x = np.tile([1.0, 0.0, 0.0], (len(normals), 1))
        x[np.abs(normals[:, 0]) > math.cos(math.radians(25.0))] = [0.0, 1.0, 0.0]
    else:
        x = np.tile(_vec3(reference, "reference"), (len(normals), 1))
    x = x - (x * normals).sum(axis=1)[:, None] * normals
    ln = np.linalg.norm(x, axis=1)
    if np.any(ln <= 1e-9):
        raise SimulationError(f"reference {reference!r} lies along the normal of receiver "
                              f"{int(np.argmax(ln <= 1e-9))}: give an axis in the receiver's plane")
    return x / ln[:, None]


def compile_seconds() -> dict[str, float]:
    """Seconds each kernel variant took to compile or load, this process: {"forward/white": s, "backward": s}."""
    return {"/".join(variant): s for variant, s in _COMPILE_SECONDS.items()}


def _is_sensor(scene, i: int) -> bool:
    fn = getattr(scene, "is_sensor", None)
    if fn is not None:
        return bool(fn(i))
    try:
        scene.instance_geometry(i)
    except Exception:
        return True
    return False
