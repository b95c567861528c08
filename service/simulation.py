"""The service's side of light transport: a `LiveScene` turned into a `tracer.simulate.Simulation`.

`SimulationHub` (one per app, ``hub_for(app)``) holds what the simulation routes keep between
requests:

- one `Simulation` per scene, built from the scene's live snapshot on first use and reused while
  nothing changes. It is built under the service's scene lock and keeps the scene's committed
  arrays (`tracer.Scene.arrays()`, which a later commit never changes: it publishes new ones), so
  a query reads a fixed revision and changes nothing; nobody copies the scene: a push never waits
  for a query and a query never sees half a push. The sync service notifies every change
  that alters what a query sees (a push, or an assignment, which keeps the revision number); the
  hub then bumps the scene's *generation* and drops what it holds for that scene. Results carry
  the revision they were computed at and the hub tells whether they are still current.
- the latest result of each grid sensor (for ``map.png``), of each surface sensor (for the view) and of each
  luminance meter and camera (for ``image.exr``, ``image.png``, ``map.png``), at the generation it was computed at
  (a camera's is also in the result store, which serves its images after a restart: `view_result`);
- the latest result of each far-field sensor (for ``export``: IES or EULUMDAT), whatever changed since (the file
  names the revision it describes); in memory: a restart forgets it;
- the `JobRunner` of async queries.

Bounds come from the service settings (``max_points``, ``max_photons``, ``max_seconds``): every
query runs with a photon and a time budget, so none can run forever; a request beyond a bound is
refused before any work. Queries in the request threads are limited to
``Settings.max_concurrent_queries`` at a time (the kernels already use every core); more wait up to
``Settings.queue_wait_seconds``, then 503.

The light transport is imported on first use: until `tracer.simulate` exists, queries answer 503
naming the missing part, never a made-up number.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from service import kind_wire, sensor_kinds
from service.errors import Invalid, NotFound, ServiceError, Unavailable
from service.jobs import JobRunner
from service.live import DELETED, LiveRegistry, LiveScene
from service.optics import to_spec
from service.payloads import result_payload
from tracer.errors import SimulationError
from tracer.optics.fields import node_field
from tracer.transport.query import DEFAULT_MAX_SECONDS, Budget, Query
from tracer.transport.query import query as make_query

log = logging.getLogger(__name__)
#: Async jobs: worker threads and how many may wait.
JOB_WORKERS = 1
MAX_QUEUED_JOBS = 16
#: Finished jobs whose results stay readable (a grid result of 100k cells is ~3 MB of JSON-ready floats).
KEEP_FINISHED_JOBS = 64
#: Budget applied when a request names no time budget (s); the settings' max_seconds caps it.


def load_transport() -> Any:
    """The `tracer.simulate` module, or `Unavailable` naming what is missing."""
    try:
        import tracer.simulate as simulate
    except ImportError as exc:
        raise Unavailable(f"the light transport (tracer.simulate, issue 6) is not available: {exc}") from exc
    if not hasattr(simulate, "Simulation"):
        raise Unavailable("tracer.simulate has no Simulation yet (issue 6): the light transport is not built")
    return simulate


def transport_lights(live: LiveScene) -> list[dict]:
    """The scene's lights as the light transport takes them (docs/CONTRACTS.md).

    The live snapshot already gives positions and directions in world metres; an area light names
    the node whose surfaces emit, which the transport needs as instance ids.
    """
    lights = []
    for light in live.lights:
        body = {k: v for k, v in light.items() if k not in ("attached_to", "name")}
        field = node_field(kind_wire.fields_of("light", body))
        if field is not None and "instances" not in body:   # a snapshot made without the scene's tree
            node = body.get(field)
            if node not in live.instance_of_node:
                raise Invalid(f"{body['type']} light {light.get('id')!r} is on node {node!r}, which has no geometry "
                              f"in revision {live.revision}", light=light.get("id"))
            body["instances"] = [live.instance_of_node[node]]
        lights.append(body)
    return lights


@dataclass
class _Cached:
    key: tuple[int, int, str]  # (revision, generation, fingerprint)
    simulation: Any
    live: LiveScene


@dataclass
class Prepared:
    """What a query runs on: the snapshot, its simulation, and the generation it belongs to."""

    live: LiveScene
    simulation: Any
    generation: int


@dataclass(frozen=True)
class Limits:
    """Bounds of one query, and of how many run at once, from the service settings."""

    max_points: int
    max_photons: int
    max_seconds: float
    max_concurrent_queries: int = 2
    queue_wait_seconds: float = 30.0
    max_camera_pixels: int = 1920 * 1080

    @classmethod
    def from_settings(cls, settings: Any) -> Limits:
        return cls(int(settings.max_points), int(settings.max_photons), float(settings.max_seconds),
                   int(settings.max_concurrent_queries), float(settings.queue_wait_seconds),
                   int(settings.max_camera_pixels))


def resolve_budget(limits: Limits, target_relative_error: float | None, max_seconds: float | None,
                   max_photons: int | None, target_scope: str = "worst") -> Budget:
    """The budget a query runs under: what the request asked, checked against the limits.

    A request beyond a limit is refused (422) rather than silently cut, so the caller knows the
    answer will not be what it asked for; where a request names no budget, the limits apply
    (seconds: the tracer's ``DEFAULT_MAX_SECONDS``, the one default, capped by the limit).
    """
    if max_photons is not None and max_photons > limits.max_photons:
        raise Invalid(f"max_photons {max_photons} exceeds this service's limit of {limits.max_photons}",
                      limit=limits.max_photons)
    if max_seconds is not None and max_seconds > limits.max_seconds:
        raise Invalid(f"max_seconds {max_seconds:g} exceeds this service's limit of {limits.max_seconds:g} s",
                      limit=limits.max_seconds)
    seconds = max_seconds if max_seconds is not None else min(DEFAULT_MAX_SECONDS, limits.max_seconds)
    photons = max_photons if max_photons is not None else limits.max_photons
    return Budget(target=target_relative_error, max_seconds=seconds, max_photons=photons, scope=target_scope)


#: the fields of a request body (`service.simulation_wire.QueryBudget`) the tracer's `Query` takes, beside the budget
QUERY_FIELDS = ("seed", "estimator", "force_effects", "force_effects_off", "observe", "reference", "physics_left_out",
                "tessellation_estimate")


def request_query(limits: Limits, wire: Any, fields: tuple[str, ...] = QUERY_FIELDS) -> Query:
    """The tracer's `Query` of a request, built once from its body (`wire`, a `QueryBudget`) and carried to the
    kernel: the budget checked against the limits (`resolve_budget`), `fields` of the body checked by the tracer
    (`tracer.transport.query.query`: 422 naming the field); what only the scene can tell is `check_query`'s."""
    budget = resolve_budget(limits, wire.target_relative_error, wire.max_seconds, wire.max_photons, wire.target_scope)
    try:
        return dataclasses.replace(make_query(**{f: getattr(wire, f) for f in fields}), budget=budget)
    except SimulationError as exc:
        raise Invalid(str(exc)) from None


def find_sensor(live: LiveScene, sensor_id: str) -> dict:
    """The live body of sensor ``sensor_id`` (raises `NotFound`)."""
    for sensor in live.sensors:
        if str(sensor.get("id")) == sensor_id:
            return sensor
    raise NotFound(f"scene {live.scene_id!r} has no sensor {sensor_id!r} in revision {live.revision}")


def _device_backend(device: str) -> Any:
    """`tracer.gpu.backend.CudaBackend` where `device` (auto, cpu, cuda) resolves to CUDA
    (`tracer.gpu.device.choose`), else None (the CPU; why is logged once by `choose`, or here)."""
    if device == "cpu":
        return None
    from tracer.gpu.device import DeviceUnavailable, choose

    try:
        if choose(device).kind != "cuda":
            return None
        from tracer.gpu.backend import CudaBackend

        return CudaBackend()
    except (DeviceUnavailable, ImportError) as exc:   # the card went away after `serve` checked it
        log.warning("device %s: computing on the CPU, because %s", device, exc)
        return None


class SimulationHub:
    """Per-app state of the simulation routes (see the module docstring).

    Parameters
    ----------
    live : LiveRegistry
        ``app.state.live``; the hub subscribes to its change notifications.
    limits : Limits
        Bounds of every query.
    build : callable(LiveScene) -> Simulation, optional
        How to make a simulation; default `tracer.simulate.Simulation` from the snapshot.
    dask_scheduler, dask_timeout : optional
        Run the batches on the Dask cluster at this address (`tracer.backends.DaskBackend`); default in this
        process. An unreachable cluster answers 503, never hangs.
    device : "auto", "cpu" or "cuda", optional
        Without a Dask cluster: where `tracer.gpu.device.choose` finds CUDA, the batches run on the card
        (`tracer.gpu.backend.CudaBackend`; a scene that does not fit there is answered on the CPU, its answer's
        `backend.fallback` saying why); else in this process.
    """

    def __init__(self, live: LiveRegistry, limits: Limits,
                 build: Callable[[LiveScene], Any] | None = None,
                 scene_lock: Callable[[str], Any] | None = None, dask_scheduler: str | None = None,
                 dask_timeout: float = 10.0, device: str = "cpu") -> None:
        self.live = live
        self.dask_scheduler, self.dask_timeout = dask_scheduler, dask_timeout
        self.device = device
        self._backend: Any = None
        self._scene_lock = scene_lock or (lambda scene_id: contextlib.nullcontext())
        self.limits = limits
        self.jobs = JobRunner(workers=JOB_WORKERS, max_queued=MAX_QUEUED_JOBS, keep_finished=KEEP_FINISHED_JOBS)
        self._build = build or self._build_default
        self._lock = threading.Lock()
        self._scene_locks: dict[str, threading.Lock] = {}
        self._generation: dict[str, int] = {}
        self._cache: dict[str, _Cached] = {}
        self._grids: dict[tuple[str, str], tuple[int, dict[str, Any]]] = {}
        self._far: dict[tuple[str, str], dict[str, Any]] = {}   # latest far-field result per (scene, sensor)
        self.results: Any = None   # service.results.ResultStore: sensor results kept past an edit (hub_for sets it)
        self._slots = threading.BoundedSemaphore(limits.max_concurrent_queries)
        live.subscribe(self.invalidate)

    # -- change tracking ----------------------------------------------------------------------

    def invalidate(self, scene_id: str, revision: int) -> None:
        """Listener for `LiveRegistry.notify`: the scene changed, so drop what was computed for it; a deleted
        scene (revision `DELETED`) also has its jobs cancelled."""
        with self._lock:
            self._generation[scene_id] = self._generation.get(scene_id, 0) + 1
            self._cache.pop(scene_id, None)
            for key in [k for k in self._grids if k[0] == scene_id]:
                del self._grids[key]
        if revision == DELETED:
            with self._lock:
                for key in [k for k in self._far if k[0] == scene_id]:
                    del self._far[key]
            self.jobs.cancel_scene(scene_id)

    def generation(self, scene_id: str) -> int:
        with self._lock:
            return self._generation.get(scene_id, 0)

    def is_current(self, scene_id: str, generation: int) -> bool:
        """Whether a result computed at ``generation`` still describes the scene."""
        return self.generation(scene_id) == generation

    # -- simulations --------------------------------------------------------------------------

    def backend(self) -> Any:
        """Where batches run (`tracer.backends`), made on first use: the Dask cluster, the CUDA card, or this
        process."""
        with self._lock:
            if self._backend is None:
                load_transport()
                from tracer.backends import IN_PROCESS, DaskBackend

                if self.dask_scheduler:
                    self._backend = DaskBackend(self.dask_scheduler, connect_timeout=self.dask_timeout,
                                                stall_timeout=self.dask_timeout)
                else:
                    self._backend = _device_backend(self.device) or IN_PROCESS
            return self._backend

    def _build_default(self, live: LiveScene) -> Any:
        simulate = load_transport()
        try:
            materials = {int(k): to_spec(v) for k, v in live.materials.items()}
            return simulate.Simulation(live.tracer, materials, transport_lights(live),
                                       default_material=to_spec(live.default_material), backend=self.backend())
        except ServiceError:
            raise
        except ValueError as exc:  # the transport refuses a body it cannot simulate, saying why
            raise Invalid(f"the scene cannot be simulated: {exc}") from exc

    def prepare(self, scene_id: str, check: Callable[[LiveScene], None] | None = None) -> Prepared:
        """The scene's current snapshot and its simulation (built once per change); raises `NotFound`. The scene's
        state is read once (`live.get`: one version check against the database), under its lock; `check(live)`
        refuses a query on that snapshot before anything is built."""
        with self._lock:
            build_lock = self._scene_locks.setdefault(scene_id, threading.Lock())
        with build_lock:  # two first queries of one scene build it once
            with self._scene_lock(scene_id):  # no push runs while we read the snapshot
                try:
                    live = self.live.get(scene_id)
                except NotFound:
                    with self._lock:   # no per-scene state is kept for an unknown id
                        self._scene_locks.pop(scene_id, None)
                    raise
                if check is not None:
                    check(live)
                generation = self.generation(scene_id)
                key = (int(live.revision), generation, live.fingerprint)
                with self._lock:
                    cached = self._cache.get(scene_id)
                if cached is not None and cached.key == key:
                    return Prepared(cached.live, cached.simulation, generation)
                simulation = self._build(live)
            with self._lock:
                if self._generation.get(scene_id, 0) == generation:
                    self._cache[scene_id] = _Cached(key, simulation, live)
            return Prepared(live, simulation, generation)

    @staticmethod
    def check_query(prepared: Prepared, query: Query) -> None:
        """Refuse (422) what the transport would refuse of this scene (an effect forced off that it requires, an
        estimator it cannot take), before a job is queued: an async request gets its error at once, not as a failed
        job. The names themselves were checked when the query was built (`request_query`)."""
        from tracer.effects import EffectError, check_off, with_forced

        force_effects = query.forced
        try:
            off = check_off(list(query.force_effects_off), force_effects, prepared.simulation.effect_reasons)
        except EffectError as exc:
            raise Invalid(str(exc)) from None
        applies = getattr(prepared.simulation, "backward_applies", None)
        if query.estimator == "backward" and applies is not None:
            ok, why = applies(with_forced(prepared.simulation.effects, force_effects, off))
            if not ok:
                raise Invalid(f"the backward estimator cannot answer here: {why}; use 'forward' or 'auto'")

    def slot(self) -> _Slot:
        """A context manager holding one of the sync-query slots (503 if none frees up in time)."""
        return _Slot(self._slots, self.limits)

    # -- queries ------------------------------------------------------------------------------

    @staticmethod
    def run_points(prepared: Prepared, points: np.ndarray, normals: np.ndarray, radius: float | None, query: Query,
                   progress: Callable | None = None, cancel: Callable | None = None) -> dict[str, Any]:
        """Illuminance at points; the JSON answer of ``POST /scenes/{id}/illuminance``."""
        with _refusals():
            result = prepared.simulation.illuminance(points, normals, radius=radius, query=query, progress=progress,
                                                     cancel=cancel)
        payload = result_payload(result, prepared.live.revision)
        if prepared.live.extras.get("elements"):   # the elements with an inside it traced, their model and its error
            payload["elements"] = prepared.live.extras["elements"]
        return payload

    def run_grid(self, prepared: Prepared, sensor: dict, query: Query, progress: Callable | None = None,
                 cancel: Callable | None = None) -> dict[str, Any]:
        """Simulate one sensor of any kind (`service.sensor_kinds`); keeps its result where its kind says (a grid's
        for ``map.png`` while the scene is unchanged, a far field's for its export)."""
        scene_id = prepared.live.scene_id
        kind = sensor_kinds.kind_of(sensor)
        kind.check(sensor, query, self.limits, prepared.live)
        run = getattr(kind, "run", None)   # a kind that splits its query (a camera's bands of rows)
        body = kind.body(sensor, prepared.live)
        with _refusals():
            if run is None:
                result = prepared.simulation.run(body, query=query, progress=progress, cancel=cancel)
            else:
                result = run(self.limits, prepared.simulation)(body, query, progress, cancel)
        payload = kind.payload(result, sensor, prepared.live)
        if prepared.live.extras.get("elements"):   # the elements with an inside it traced, and their model
            payload["elements"] = prepared.live.extras["elements"]
        if kind.KEEP == "far":
            if not cancel or not cancel():
                with self._lock:
                    self._far[(scene_id, str(sensor["id"]))] = payload
                if self.results is not None:   # the export outlives a restart
                    self.results.keep_far(scene_id, str(sensor["id"]), payload)
            return payload
        with self._lock:
            if self._generation.get(scene_id, 0) == prepared.generation and kind.KEEP in ("map", "image"):
                self._grids[(scene_id, str(sensor["id"]))] = (prepared.generation, payload)
        if self.results is not None and self.is_current(scene_id, prepared.generation):
            self.results.keep(prepared.live, sensor, payload)
        return payload

    def far_result(self, scene_id: str, sensor_id: str) -> dict[str, Any] | None:
        """The latest result of a far-field sensor (whatever changed since; it names its revision), else None: from
        memory, else as kept in the database (a result of an earlier run of the service)."""
        with self._lock:
            payload = self._far.get((scene_id, sensor_id))
        if payload is None and self.results is not None:
            payload = self.results.far(scene_id, sensor_id)
            if payload is not None:
                with self._lock:
                    self._far.setdefault((scene_id, sensor_id), payload)
        return payload

    def grid_result(self, scene_id: str, sensor_id: str) -> dict[str, Any] | None:
        """The latest result of a grid (or surface) sensor while the scene is unchanged since, else None."""
        with self._lock:
            entry = self._grids.get((scene_id, sensor_id))
            if entry is None or entry[0] != self._generation.get(scene_id, 0):
                return None
            return entry[1]

    def view_result(self, scene_id: str, sensor: dict[str, Any]) -> dict[str, Any] | None:
        """The latest result of a luminance meter or camera while it still describes the scene: from memory, else
        the kept one of the scene's revision and state (`service.results.ResultStore.current`: a result of an
        earlier run of the service), with its JSON fields as a fresh answer names them."""
        payload = self.grid_result(scene_id, str(sensor["id"]))
        if payload is not None or self.results is None:
            return payload
        kept = self.results.current(self.live.get(scene_id), sensor)
        if kept is None:
            return None
        kept.setdefault("position", sensor.get("position"))
        kept.setdefault("look_at", sensor.get("look_at"))
        return {**kept, "estimator": kept.get("estimator", "backward"), "kept": kept["key"]}

    def shutdown(self) -> None:
        self.jobs.shutdown(wait=1.0)
        close = getattr(self._backend, "close", None)
        if close is not None:
            close()


@contextlib.contextmanager
def _refusals() -> Any:
    """Map the transport's refusal of a query (a ValueError saying why) to a 422, and an unreachable compute
    backend (`tracer.backends.BackendUnavailable`) to a 503."""
    try:
        yield
    except ServiceError:
        raise
    except RuntimeError as exc:
        if type(exc).__name__ == "BackendUnavailable":
            raise Unavailable(str(exc), retry_after_seconds=10) from exc
        raise
    except ValueError as exc:
        raise Invalid(f"the light transport refused the query: {exc}") from exc


SLOT_POLL_SECONDS = 0.02   # how often a query waiting for a sync slot looks again


class _Slot:
    def __init__(self, semaphore: threading.BoundedSemaphore, limits: Limits) -> None:
        self._semaphore = semaphore
        self._limits = limits

    def __enter__(self) -> None:
        if not self._semaphore.acquire(timeout=self._limits.queue_wait_seconds):
            raise Unavailable(f"{self._limits.max_concurrent_queries} queries are running; try again later or use "
                              f"?mode=async", retry_after_seconds=5)

    def __exit__(self, *exc: object) -> None:
        self._semaphore.release()

    async def __aenter__(self) -> None:
        """Wait for a slot without holding a thread: the event loop polls the semaphore (every
        `SLOT_POLL_SECONDS`), so fifty queued queries leave every worker thread free for other requests."""
        deadline = time.monotonic() + self._limits.queue_wait_seconds
        while not self._semaphore.acquire(blocking=False):
            if time.monotonic() >= deadline:
                raise Unavailable(f"{self._limits.max_concurrent_queries} queries are running; try again later or "
                                  f"use ?mode=async", retry_after_seconds=5)
            await asyncio.sleep(SLOT_POLL_SECONDS)

    async def __aexit__(self, *exc: object) -> None:
        self._semaphore.release()


_HUB_LOCK = threading.Lock()


def hub_for(app: Any) -> SimulationHub:
    """The app's `SimulationHub`, made on first use from ``app.state.live`` and ``app.state.settings``."""
    hub = getattr(app.state, "simulation_hub", None)
    if hub is not None:
        return hub
    with _HUB_LOCK:
        hub = getattr(app.state, "simulation_hub", None)
        if hub is None:
            settings = getattr(app.state, "settings", None)
            if settings is None:
                from service.config import Settings

                settings = Settings()
            live = app.state.live
            hub = SimulationHub(live, Limits.from_settings(settings), scene_lock=live.lock,
                                dask_scheduler=settings.dask_scheduler, dask_timeout=settings.dask_timeout,
                                device=getattr(settings, "device", "cpu"))
            engine = getattr(app.state, "engine", None)
            if engine is not None:
                from service.results import ResultStore

                hub.results = ResultStore(engine, getattr(settings, "keep_results", 20))
            app.state.simulation_hub = hub
    return hub

