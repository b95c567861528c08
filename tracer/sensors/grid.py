"""Grid: the illuminance (lx) averaged over each cell of a rectangle origin + s u + t v, front side u × v.

``{"type": "grid", "origin": (3,) m, "u": (3,) m, "v": (3,) m, "nu": 1..4096, "nv": 1..4096}``. Both estimators
answer it ("auto" takes forward). The answer: `GridResult`, ``lux`` and ``stderr`` (nv, nu), row j the v-cell j
(observed spectra and chromaticities (nv, nu, …)).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from tracer.errors import SimulationError
from tracer.optics.fields import BodyField, fields
from tracer.sensors.base import IlluminanceResult, Probe, vec3
from tracer.sensors.placement import place_receivers

TYPE = "grid"
FORWARD_ONLY = False
OBSERVES = True
MAX_CELLS_PER_SIDE = 4096


@dataclass
class GridResult(IlluminanceResult):
    """Illuminance of a grid sensor: `lux` and `stderr` have shape (nv, nu); row j is v-cell j."""


FIELDS = fields(
    BodyField("origin", "point", "A corner of the rectangle [x, y, z], m."),
    BodyField("u", "vector", "The edge along which the nu cells lie, m (its length is the width)."),
    BodyField("v", "vector", "The edge along which the nv cells lie, m; u × v is the side facing the light."),
    BodyField("nu", "count", "Cells along u.", lo=1, hi=MAX_CELLS_PER_SIDE),
    BodyField("nv", "count", "Cells along v.", lo=1, hi=MAX_CELLS_PER_SIDE))
EXAMPLE = {"type": "grid", "name": "floor grid", "origin": [-2.0, -2.0, 0.01], "u": [4.0, 0.0, 0.0],
           "v": [0.0, 4.0, 0.0], "nu": 20, "nv": 20}


def check(body: dict) -> tuple:
    """The body checked: (origin, u, v, nu, nv, the unit normal u × v)."""
    o, uu, vv = vec3(body.get("origin"), "origin"), vec3(body.get("u"), "u"), vec3(body.get("v"), "v")
    nu: Any = body.get("nu")
    nv: Any = body.get("nv")
    for name, val in (("nu", nu), ("nv", nv)):
        lo, hi = int(FIELDS[name].lo), int(FIELDS[name].hi)
        if isinstance(val, bool) or not isinstance(val, int | np.integer) or not lo <= val <= hi:
            raise SimulationError(f"{name} must be an integer in [{lo}, {hi}], got {val!r}")
    nrm = np.cross(uu, vv)
    ln = float(np.linalg.norm(nrm))
    if not ln > 1e-12 * float(np.linalg.norm(uu) * np.linalg.norm(vv)) or ln == 0.0:
        raise SimulationError("u and v must be non-zero and not parallel")
    return o, uu, vv, int(nu), int(nv), nrm / ln


def probe(sim, body: dict) -> Probe:
    o, uu, vv, nu, nv, nrm = check(body)
    centre = o + 0.5 * (uu + vv)
    half_diagonal = 0.5 * float(np.linalg.norm(uu + vv))
    o = o + (place_receivers(sim.arrays, centre[None, :], nrm[None, :], half_diagonal)[0] - centre) @ nrm * nrm
    return Probe(o, nrm, 0.0, (uu, vv, nu, nv))


def answer(sim, probe: Probe, res: IlluminanceResult) -> GridResult:
    grid: Any = probe.grid
    nu, nv = grid[2], grid[3]
    shape = (nv, nu)

    def cells(a):
        return None if a is None else a.reshape(shape + a.shape[1:])

    out = GridResult(cells(res.lux), cells(res.stderr), res.nm, cells(res.spectral_irradiance),
                     cells(res.spectral_stderr), cells(res.cie_xy), cells(res.stokes), cells(res.stokes_stderr),
                     cells(res.dop), res.cost, **res.readout())
    if res.error_budget is not None:
        out.error_budget = {name: cells(v) if np.ndim(v) else v for name, v in res.error_budget.items()}  # costs stay
    if res.physics_left_out is not None:
        out.physics_left_out = {name: {**e, "difference": cells(e["difference"]), "stderr": cells(e["stderr"])}
                                for name, e in res.physics_left_out.items()}
    return out
