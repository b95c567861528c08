"""The contract of a sensor kind, and what every kind's answer starts from.

A sensor kind is one module of this folder, registered by one line in `tracer.sensors.dispatch.KINDS`. It holds:

- ``TYPE`` : str — its name in a sensor body (``{"type": TYPE, ...}``), as on the wire (docs/DESIGN.md);
- ``FORWARD_ONLY`` : bool — only photons from the sources reach its bins (no backward path ends there);
- ``OBSERVES`` : bool — it can answer ``observe`` (spectrum, Stokes) and ``physics_left_out``;
- ``FIELDS`` — its body fields, typed (`tracer.optics.fields`), for a kind a scene keeps as a sensor: the service
  makes the kind's wire model from them (a ``node`` field: the tracer's body holds ``instances``, the ids of the
  node's instances, instead); None for a kind only a query's body asks for (``points``). ``EXAMPLE`` (optional): a
  body the API docs show;
- ``check(body)`` — the body checked without a scene (`tracer.errors.SimulationError` saying which field is wrong
  and why), reading its bounds from ``FIELDS``; the service's wire model runs it too, so both sides refuse alike;
- ``probe(sim, body) -> Probe`` — the body checked (``check``, then what only the scene can tell, before anything
  runs) and turned into receivers in the scene's world (metres);
- ``answer(sim, probe, res) -> result`` — the raw bins (`IlluminanceResult`: one value per bin, in bin order) put
  in the kind's shape and units, with the run's photons, seconds, effects, estimator, stop reason, cost and backend.

What a photon or a path adds to the bins is the kernels' (`tracer.transport.forward.SensorArrays`,
`tracer.transport.backward`): a receiver crossed from its front side adds the photon's flux; bins are divided by
their area (lx), a far field's by its solid angle (cd). `tracer.transport.rounds` runs the batches; the estimate's
standard error is that of batch means.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from tracer.errors import SimulationError


@dataclass
class Probe:
    """A sensor's receivers, as the rounds trace them.

    centers : (k, 3) float, m — disk receiver centres (moved onto the surface they lie on and in front of it), or a
        grid's origin (3,) (likewise moved); (0, 3) where the kind has no receivers.
    normals : (k, 3) unit front-side normals, or a grid's (3,) normal.
    radius : float, m — the disks' radius (0 for a grid).
    grid : (u, v, nu, nv) or None — a grid's edge vectors (m) and cells.
    surface : (surf (n_instances,) int64 first bin per tallied instance or -1, areas (n,) m²) or None.
    far : (far-field parameters, solid angles (nγ·nc,) sr) or None.
    view : `tracer.transport.radiance.ViewArrays` or None — the directions a luminance meter or a camera looks
        along (then the run traces paths from the eye, and its bins are luminances, cd/m²).
    keep : what `answer` needs back (instance ids, areas, the far field's frame), kind by kind.
    """

    centers: np.ndarray
    normals: np.ndarray
    radius: float = 0.0
    grid: tuple | None = None
    surface: tuple | None = None
    far: tuple | None = None
    view: Any = None
    keep: dict[str, Any] = field(default_factory=dict)

    @property
    def is_grid(self) -> bool:
        return self.grid is not None


@dataclass(kw_only=True)
class Readout:
    """What every sensor's answer says of its run (keyword fields, after the kind's own).

    photons : int — photons (forward) or paths (backward, all points together) traced.
    seconds : float — wall time of the query.
    effects : list[str] — the effect set of the kernel that ran.
    estimator : "forward" or "backward".
    stop_reason : "target_relative_error", "max_photons", "max_seconds" or "cancelled".
    batches : int; rejected : int — samples dropped as non-finite (never tallied);
    counters : dict — every kernel counter; compile_seconds : float — spent compiling (or loading
    from numba's cache) a kernel variant used for the first time in this process.
    backend : dict — where the batches ran (`tracer.backends`): {"name": "in-process", "threads": n} or
    {"name": "dask", "address": …, "workers": n, "threads": n}.
    effect_reasons : dict or None — for every effect (`tracer.effects.EFFECTS`), why it was on or off in this run
    (`tracer.effects.explain_effects`, as the query forced it).
    """

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
    effect_reasons: dict | None = None

    def readout(self) -> dict[str, Any]:
        """The run's fields, to pass on to the kind's answer (``Answer(..., **raw.readout())``)."""
        return {f.name: getattr(self, f.name) for f in fields(Readout)}


@dataclass
class IlluminanceResult(Readout):
    """Illuminance at query points.

    lux, stderr : (k,) float64, lx — patch-average illuminance and its standard error; the run's fields as for
    `Readout`.
    Where the query observes the spectrum: nm (N_BINS,) — centres of the 5 nm bands;
    spectral_irradiance, spectral_stderr (k, N_BINS) — W/m²/nm in each band and its standard error;
    cie_xy (k, 2) — CIE 1931 chromaticity of the light arriving (NaN where nothing arrived).
    cost : dict — what tighter errors would cost on this scene and machine (`tracer.transport.estimate.cost_of`).
    error_budget : dict or None — ``{"tessellation": (k,) lx}`` where the scene holds curved optical surfaces
    (mirror or glass meshes with vertex normals): how far each value may move when they are tessellated finely
    enough (`tracer.transport.tessellation_error`); None elsewhere.
    physics_left_out : dict or None — where the query asked (`Simulation.left_out`): per effect,
    ``{"difference": (k,) lx, "stderr": (k,) lx, "photons", "seconds", "estimator", "ran"}``, the lux with that
    effect forced on minus `lux`.
    Where the query observes Stokes (`tracer.optics.polarization`): stokes, stokes_stderr (k, 4) — lx, S0 = lux,
    in each receiver's frame (x axis: its `reference` in its plane, taken across each photon's direction);
    dop (k,) — degree of polarization √(S1² + S2² + S3²) / S0 (NaN where nothing arrived).
    """

    lux: np.ndarray
    stderr: np.ndarray
    nm: np.ndarray | None = None
    spectral_irradiance: np.ndarray | None = None
    spectral_stderr: np.ndarray | None = None
    cie_xy: np.ndarray | None = None
    stokes: np.ndarray | None = None
    stokes_stderr: np.ndarray | None = None
    dop: np.ndarray | None = None
    cost: dict | None = None
    error_budget: dict | None = None
    physics_left_out: dict | None = None


def vectors(a, name: str, k: int | None = None) -> np.ndarray:
    """`a` as a finite (k, 3) float64 array; `SimulationError` naming `name` otherwise."""
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


def vec3(a, name: str) -> np.ndarray:
    """`a` as 3 finite float64 numbers; `SimulationError` naming `name` otherwise."""
    try:
        v = np.asarray(a, dtype=np.float64)
    except (TypeError, ValueError):
        raise SimulationError(f"{name} must be 3 numbers") from None
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise SimulationError(f"{name} must be 3 finite numbers, got {a!r}")
    return v
