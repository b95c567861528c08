"""Surface: the illuminance on the model itself, per triangle of each instance listed.

``{"type": "surface", "instances": [instance ids]}``: the luminous flux arriving on each triangle's front side (the
side its geometric normal points to, object-space e1 × e2 mapped to world: the outside of a CAD solid; light
arriving from behind is not counted) divided by its world area (the instance's transform applied), averaged over the
triangle. Forward only: the kernel adds each photon's weight where it hits a tallied triangle, before the surface
scatters it (`tracer.transport.forward.SensorArrays.surf`), which observes and changes nothing: every path and every
other tally of the same query is bit-identical with and without it. Its error stop looks at every triangle (one that
received nothing so far counts as converged), so a target error on a fine mesh is reached late: give it a photon or
time budget. The answer: `SurfaceResult`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from tracer.errors import SimulationError
from tracer.optics.fields import BodyField, fields
from tracer.sensors.base import IlluminanceResult, Probe, Readout
from tracer.transport.rounds import MAX_SPECTRAL_TALLIES

TYPE = "surface"
FORWARD_ONLY = True
OBSERVES = False


@dataclass
class SurfaceResult(Readout):
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


FIELDS = fields(BodyField("node", "node", "The node (UUID or path) whose surfaces, with its descendants', are "
                                          "tallied; it or a descendant must have geometry."))
EXAMPLE = {"type": "surface", "node": "room/floor", "name": "the floor in lux"}


def check(body: dict) -> list[int]:
    """The body checked: the instance ids, each once (whether the scene holds them is `probe`'s)."""
    instances: Any = body.get("instances")
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
    return ids


def probe(sim, body: dict) -> Probe:
    ids = check(body)
    scene = sim.scene
    known = {int(i) for i in scene.instances()}
    n_inst = max(known) + 1 if known else 0
    surf = np.full(max(n_inst, max(ids) + 1), -1, np.int64)
    areas = []
    base = 0
    for i in ids:
        if i not in known:
            raise SimulationError(f"instances: {i} is not an instance of the scene")
        if i in sim.sensor_ids:
            raise SimulationError(f"instances: {i} is a sensor, it has no surface to tally")
        verts, tris, _ = scene.geometry_arrays(scene.instance_geometry(i))
        m = np.asarray(scene.instance_transform(i), np.float64)[:3, :3]
        w = np.asarray(verts, np.float64) @ m.T
        t = np.asarray(tris, np.int64)
        a = 0.5 * np.linalg.norm(np.cross(w[t[:, 1]] - w[t[:, 0]], w[t[:, 2]] - w[t[:, 0]]), axis=1)
        surf[i] = base
        base += len(a)
        areas.append(a)
    if base > MAX_SPECTRAL_TALLIES:
        raise SimulationError(f"the instances hold {base} triangles: at most {MAX_SPECTRAL_TALLIES} are tallied")
    return Probe(np.empty((0, 3)), np.empty((0, 3)), surface=(surf, np.concatenate(areas)),
                 keep={"ids": ids, "areas": areas})


def answer(sim, probe: Probe, res: IlluminanceResult) -> SurfaceResult:
    lux, err, out_a = [], [], []
    at = 0
    for a in probe.keep["areas"]:
        lux.append(res.lux[at:at + len(a)])
        err.append(res.stderr[at:at + len(a)])
        out_a.append(a)
        at += len(a)
    return SurfaceResult(probe.keep["ids"], lux, err, out_a, **res.readout())
