"""Far field: the luminous intensity (cd) of the whole scene as a lamp, on a type-C grid.

``{"type": "far_field", "nc": 1..3600, "ngamma": 2..1801, "direction": (3,) (default −z, the nadir), "c0": (3,)
(default +x, +y where direction lies along x)}``: γ from `direction`, C from `c0` (only its part across `direction`
counts), C = 90° along c0 × direction, as a goniometric light's (`tracer.photometry.files`). Every photon that leaves
the scene (its ray meets nothing) is binned by its direction, I = flux in the bin / the bin's solid angle. A far field:
the scene is taken as a point, small against the viewing distance (a photometric distance of five or more times the
luminaire's largest dimension, the usual rule): where the lamp is seen from nearer, its size matters and this answer
does not hold. Forward only; it observes and changes nothing (`tracer.transport.forward.SensorArrays.far`); the error
stop looks at every bin (an empty one counts as converged). The answer: `FarFieldResult`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from tracer.errors import SimulationError
from tracer.optics.fields import BodyField, fields
from tracer.sensors.base import IlluminanceResult, Probe, Readout, vec3
from tracer.transport.rounds import MAX_SPECTRAL_TALLIES

TYPE = "far_field"
FORWARD_ONLY = True
OBSERVES = False


@dataclass
class FarFieldResult(Readout):
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


FIELDS = fields(
    BodyField("nc", "count", "C samples (dimensionless count): C_i = i·360°/nc, each owning ±180°/nc around it; 1 for "
              "an axially symmetric distribution.", lo=1, hi=3600),
    BodyField("ngamma", "count", "γ samples (dimensionless count): γ_j = j·180°/(ngamma−1) from 0° to 180°, each "
              "owning ±half a step (the two polar caps are one bin each).", lo=2, hi=1801),
    BodyField("direction", "direction", "The γ = 0 axis (dimensionless, any length); default −z, straight down.",
              required=False),
    BodyField("c0", "direction", "The C = 0 half-plane's direction (dimensionless; its part across `direction` "
              "counts); default +x. C = 90° lies along c0 × direction.", required=False))
EXAMPLE = {"type": "far_field", "name": "downlight far field", "nc": 24, "ngamma": 37, "direction": [0.0, 0.0, -1.0],
           "c0": [1.0, 0.0, 0.0]}


def check(body: dict) -> tuple:
    """The body checked: (nc, ngamma, the unit γ = 0 axis, the unit C = 0 and C = 90° axes)."""
    nc: Any = body.get("nc")
    ngamma: Any = body.get("ngamma")
    direction: Any = body.get("direction", (0.0, 0.0, -1.0))
    c0: Any = body.get("c0")
    for name, val in (("nc", nc), ("ngamma", ngamma)):
        lo, hi = int(FIELDS[name].lo), int(FIELDS[name].hi)
        if isinstance(val, bool) or not isinstance(val, int | np.integer) or not lo <= val <= hi:
            raise SimulationError(f"{name} must be an integer in [{lo}, {hi}], got {val!r}")
    nc, ngamma = int(nc), int(ngamma)
    axis = vec3(direction, "direction")
    given = c0 is not None
    t = vec3(c0 if given else (1.0, 0.0, 0.0), "c0")
    if not np.linalg.norm(axis) > 0:
        raise SimulationError("direction must be a non-zero vector")
    axis = axis / np.linalg.norm(axis)
    t = t - axis * float(t @ axis)
    if not given and not np.linalg.norm(t) > 1e-9:
        t = np.array([0.0, 1.0, 0.0]) - axis * axis[1]
    if not np.linalg.norm(t) > 1e-9 * max(1.0, float(np.linalg.norm(c0 if given else t))):
        raise SimulationError(f"c0 {list(map(float, c0))} must not be parallel to direction "
                              f"{list(map(float, direction))}")
    t = t / np.linalg.norm(t)
    b = np.cross(t, axis)   # C = 90°: c0 × direction (+y for the defaults)
    return nc, ngamma, axis, t, b


def probe(sim, body: dict) -> Probe:
    nc, ngamma, axis, t, b = check(body)
    if nc * ngamma > MAX_SPECTRAL_TALLIES:   # what a run can tally: the query's limit, not the body's
        raise SimulationError(f"nc × ngamma = {nc * ngamma} bins: at most {MAX_SPECTRAL_TALLIES}")
    c_deg, gamma_deg, omega = far_field_bins(nc, ngamma)
    return Probe(np.empty((0, 3)), np.empty((0, 3)), far=((nc, ngamma, *axis, *t, *b), omega.ravel()),
                 keep={"nc": nc, "ngamma": ngamma, "axis": axis, "c0": t, "c_deg": c_deg, "gamma_deg": gamma_deg,
                       "omega": omega})


def answer(sim, probe: Probe, res: IlluminanceResult) -> FarFieldResult:
    k = probe.keep
    nc, ngamma = k["nc"], k["ngamma"]
    cd = res.lux[:-1].reshape(ngamma, nc).copy()
    err = res.stderr[:-1].reshape(ngamma, nc).copy()
    for j in (0, ngamma - 1):   # a polar cap is one bin, tallied in its C = 0 column
        cd[j, :] = cd[j, 0]
        err[j, :] = err[j, 0]
    return FarFieldResult(cd, err, k["c_deg"], k["gamma_deg"], k["omega"], float(res.lux[-1]), float(res.stderr[-1]),
                          k["axis"], k["c0"], **res.readout())
