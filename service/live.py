"""The live view of a scene that the simulation routes read (docs/CONTRACTS.md, "service core → simulation routes").

`LiveScene` is a snapshot of one scene revision: the committed `tracer.Scene`, world transforms
of every document node in metres, the effective material of every instance (inheritance
applied), and the lights and sensors resolved to world metres (attached ones moved with their
node). `LiveRegistry.get(scene_id)` returns it; the registry is `app.state.live`.

Conventions: every length is in metres, every transform a 4×4 ``world_from_node`` (row-major
numpy float64) whose linear part is the node's rotation (and any scale the document itself
carries); coordinates in a node's frame are metres too.

The snapshot is built lazily, at most once per (revision, assignment change), so a push does
not pay for it. The `tracer` object is shared with the sync service: a later push mutates it
in place (and commits before it lets go of the scene's lock), so a long query should compare
`revision` with `LiveRegistry.revision(scene_id)` when it ends if it wants to know that its
answer is stale. ``LiveRegistry.lock(scene_id)`` is that lock (re-entrant): hold it while taking
``tracer.arrays()`` or copying the scene, to never see a scene between a change and its commit.

With several service processes on one database, `get`, `revision` and `lock` first bring the scene up to
date with what the others committed (one SELECT; `service.scenes.Scenes.state`), and a scene changed
through another process notifies the listeners here like a change made through this one.

`scene_effects(live)` is a live scene's effect set (the scene summary and the simulation both ask it).
"""

from __future__ import annotations

import functools
import hashlib
import json
from collections.abc import Callable
from contextlib import AbstractContextManager
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    import tracer


DELETED = -1   # the revision a notification carries when its scene was deleted


#: the material of a surface nobody assigned one to (stated in `GET /scenes/{id}`)
DEFAULT_MATERIAL: dict[str, Any] = {"type": "lambertian", "reflectance": 0.5}


@dataclass
class LiveScene:
    """One scene revision as the simulation sees it (all lengths in metres)."""

    scene_id: str
    revision: int
    tracer: tracer.Scene  # committed
    instance_of_node: dict[str, int]  # node uuid (or sim-owned object id) -> instance id
    node_world: dict[str, np.ndarray]  # node uuid -> 4x4 world_from_node, metres
    materials: dict[int, dict]  # instance id -> effective material body (inheritance applied)
    default_material: dict
    lights: list[dict]  # light bodies with "id", in world metres (attached ones resolved)
    sensors: list[dict]  # sensor bodies with "id", in world metres
    extras: dict[str, Any] = field(default_factory=dict)  # room for later additions, never required

    @functools.cached_property
    def fingerprint(self) -> str:
        """A digest of everything besides geometry that a `Simulation` is built from, computed once per snapshot
        (a snapshot is never changed after it is made: a change makes a new one). The simulation hub rebuilds on
        every notification anyway; the fingerprint guards a change that did not notify (a snapshot rebuilt from
        the database after a restart, say)."""
        elements = self.extras.get("elements")   # what carries an element with an inside, where anything does
        payload = json.dumps([self.revision, sorted((int(k), v) for k, v in self.materials.items()),
                              self.default_material, self.lights] + ([elements] if elements else []), sort_keys=True,
                             default=str)
        return hashlib.sha256(payload.encode()).hexdigest()


class LiveRegistry:
    """`app.state.live`: the live scenes of this process.

    Parameters
    ----------
    build : callable(scene_id) -> LiveScene
        Builds (or returns a cached) snapshot; raises `service.errors.NotFound` for an unknown scene.
    revision : callable(scene_id) -> int
        The scene's current revision, cheap (no snapshot built).
    lock : callable(scene_id) -> context manager
        The scene's (re-entrant) lock: no push or assignment changes the scene while it is held.
    """

    def __init__(self, build: Callable[[str], LiveScene], revision: Callable[[str], int],
                 lock: Callable[[str], AbstractContextManager[Any]]) -> None:
        self._build = build
        self._revision = revision
        self._lock = lock
        self._listeners: list[Callable[[str, int], None]] = []

    def get(self, scene_id: str) -> LiveScene:
        """The scene's current snapshot; raises `service.errors.NotFound` if there is no such scene."""
        return self._build(scene_id)

    def revision(self, scene_id: str) -> int:
        """The scene's current revision (raises `service.errors.NotFound`)."""
        return self._revision(scene_id)

    def lock(self, scene_id: str) -> AbstractContextManager[Any]:
        """Hold it to read or copy the scene with no push or assignment change in between."""
        return self._lock(scene_id)

    def subscribe(self, listener: Callable[[str, int], None]) -> None:
        """Call ``listener(scene_id, new_revision)`` after every change that alters the live view.

        Pushes and assignment changes both notify (an assignment change keeps the revision number but
        changes what a query sees); a listener may, for example, drop cached results of that scene. A
        deleted scene notifies with the revision `DELETED`.
        """
        self._listeners.append(listener)

    def notify(self, scene_id: str, revision: int) -> None:
        """Tell every listener that `scene_id` changed (called by the sync service)."""
        for listener in list(self._listeners):
            listener(scene_id, revision)


def scene_effects(live: LiveScene, uses_default: bool = True) -> list[str]:
    """The scene's effect set, by the transport's one rule (`tracer.effects.derive_effects`) over its
    materials (and the default material where some instance uses it) and its lights. A body stored under older, looser
    rules that the tracer now refuses is left out here (a summary never fails); a query says what is wrong."""
    # imported on first use, not to dodge a circle: the tracer's numba start-up is not paid by /health
    from tracer.effects import derive_effects
    from tracer.optics.surfaces.dispatch import MaterialError, material_spec

    specs = []
    for body in list(live.materials.values()) + ([live.default_material] if uses_default else []):
        try:
            specs.append(material_spec(body))
        except MaterialError:
            continue
    return derive_effects(specs, live.lights)
