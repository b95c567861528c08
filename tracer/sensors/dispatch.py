"""The one place that picks a sensor kind by its ``type`` (see `tracer.sensors.base` for the contract).

To register a new kind: import its module here and add it to `KINDS`.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from tracer.errors import SimulationError
from tracer.sensors import camera, disk, far_field, grid, luminance, points, surface

#: every registered sensor kind, by its body's ``type``
KINDS = {m.TYPE: m for m in (points, disk, grid, surface, far_field, luminance, camera)}


def kind_of(body: Any):
    """The kind module of a sensor body (a dict with ``type``); `SimulationError` saying what is known otherwise."""
    if not isinstance(body, dict):
        raise SimulationError(f"a sensor is a dict {{'type': one of {sorted(KINDS)}, ...}}, got {type(body).__name__}")
    kind = KINDS.get(body.get("type"))
    if kind is None:
        raise SimulationError(f"sensor type {body.get('type')!r} is unknown; known: {sorted(KINDS)}")
    return kind


def run(sim, body: dict, query, progress=None, cancel=None) -> Any:
    """Measure one sensor on `sim` (`tracer.simulate.Simulation`) for `query` (`tracer.transport.query.Query`): its
    probe, the rounds, its answer. A kind that is forward only answers "auto" forward; one that does not observe
    refuses ``observe`` and ``physics_left_out``."""
    kind = kind_of(body)
    if not kind.OBSERVES and (query.observe or query.physics_left_out):
        raise SimulationError(f"a {kind.TYPE} sensor takes no observe or physics_left_out")
    if kind.FORWARD_ONLY and query.estimator == "auto":
        query = dataclasses.replace(query, estimator="forward")
    return kind.answer(sim, *sim.measure(kind.probe, body, query, progress, cancel))
