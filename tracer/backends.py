"""Where a query's photon batches run: threads of this process, or tasks on a Dask cluster.

The contract (docs/CONTRACTS.md, "light transport → backends"). A backend runs batches
``batch0 … batch0 + n_batches − 1`` of a named kernel and returns ``(values, counters)``, numpy arrays
of shape (n_batches, bins) and (n_batches, counters), in batch order:

    backend.run(kernel_id, scene: Shipment, query: Shipment, batch0, n_batches, size)
    backend.describe() -> {"name": "in-process", "threads": 2} | {"name": "dask", "address": …, "workers": 2, …}
    backend.shape -> BatchShape   # how a query's work is cut into batches and rounds for it

A backend's `BatchShape` says how `tracer.simulate` cuts a query for it: photons per forward batch, paths per patch
per backward batch, the batches of a first round and of the largest. The CPU's (`CPU_SHAPE`: 20,000 photons, 8 to
128 batches) keeps threads and Dask workers busy for 0.1 s a task; a GPU, which runs one batch per thread, wants
thousands of small batches a round (`tracer.gpu.backend.GPU_SHAPE`). Answers are bit-identical wherever batches of
one shape run; two shapes draw different random numbers (the same seed, other batches) and agree within their
error bars.

``kernel_id`` names a kernel that any process with `tracer` can make: ``("forward", photon_state)`` or
``("backward",)`` (`run_kernel`). A `Shipment` is the read-only data a kernel takes, with a content key:
the scene's snapshot (committed arrays, materials, lights) is one shipment per revision and photon state,
the query's receivers another. Each batch is seeded by its index (`tracer.rng`), so however the batches
are split (threads, tasks, workers, a re-run after a lost worker) the values are bit-identical.

`DaskBackend` sends a snapshot to the workers once (``scatter(broadcast=True)``, keyed by its content),
keeps it there while the backend holds it (the most recent, at most `DaskBackend.KEEP_SHIPMENTS` of them and
`DaskBackend.KEEP_BYTES` together: a large scene's old revisions do not pile up on every worker), and splits each round
of batches into one task per worker thread: a task of several batches of 20,000 photons runs for 0.1 s
or more, far above Dask's ~1 ms per task. A worker compiles (or loads from numba's cache) each kernel
once, in its own process. A worker lost mid-round has its tasks re-run elsewhere by the scheduler; a
snapshot lost with it is sent again. An unreachable scheduler raises `BackendUnavailable` within
`connect_timeout` seconds, never a hang.
"""

from __future__ import annotations

import hashlib
import logging
import sys
import threading
import time
import uuid
from collections import OrderedDict, deque
from typing import Any, NamedTuple

import numba
import numpy as np

from tracer.errors import TracerError

log = logging.getLogger(__name__)

KernelId = tuple[str, ...]


class BatchShape(NamedTuple):
    """How a query is cut for a backend (see the module docstring)."""

    forward_photons: int = 20_000   # photons per forward batch (fewer when a query's max_photons is small)
    backward_paths: int = 32        # paths per query patch per backward batch
    first_round: int = 8            # batches started between two stop tests, at first
    max_round: int = 128            # the largest round (rounds grow to a quarter of the batches run so far)


CPU_SHAPE = BatchShape()


class BackendUnavailable(TracerError, RuntimeError):
    """The compute backend cannot be reached (the message says which and why); retry later. A `TracerError`
    (the package's one root) and a RuntimeError: not bad input, so callers that map ValueError to 422 test
    for it first."""


class Shipment:
    """Read-only arguments of a kernel (a tuple of arrays, NamedTuples of arrays and numbers), with a content
    key computed once: BLAKE2b over every array's dtype, shape and bytes, in order."""

    __slots__ = ("_key", "_nbytes", "parts")

    def __init__(self, parts: tuple) -> None:
        self.parts = parts
        self._key: str | None = None
        self._nbytes: int | None = None

    @property
    def nbytes(self) -> int:
        """Bytes of all its arrays (what a worker holds of it)."""
        if self._nbytes is None:
            self._nbytes = nbytes(self.parts)
        return self._nbytes

    @property
    def key(self) -> str:
        if self._key is None:
            h = hashlib.blake2b(digest_size=16)
            _digest(h, self.parts)
            self._key = h.hexdigest()
        return self._key


def nbytes(obj: Any) -> int:
    """Bytes of every array in `obj` (an array, or tuples and NamedTuples of arrays and numbers)."""
    if isinstance(obj, np.ndarray):
        return int(obj.nbytes)
    if isinstance(obj, tuple | list):
        return sum(nbytes(item) for item in obj)
    return 0


def _digest(h: Any, obj: Any) -> None:
    if isinstance(obj, np.ndarray):
        a = np.ascontiguousarray(obj)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.data.cast("B") if a.size else b"")
    elif isinstance(obj, tuple | list):
        h.update(f"({type(obj).__name__}{len(obj)}".encode())
        for item in obj:
            _digest(h, item)
    else:
        h.update(repr(obj).encode())


_BOUND: list = []   # [[sa, mats, lights, bound mats, bound lights, join table or None]], the most recent first: the
_BOUND_KEEP = 4     # next rounds of the queries running now (a pool thread takes their chunks in turn: one entry
_BOUND_LOCK = threading.Lock()   # would bind at each)


def _bound(sa, mats, lights, joins: bool = False) -> tuple:
    """The materials and lights with this process's kind addresses (`tracer.jit.kind_table`), and with `joins` the
    table of the join through glass (`tracer.transport.through_flat.bind`; else None); a query's later rounds reuse
    its first round's (binding types the tuples: about a millisecond a call)."""
    from tracer.optics.lights.dispatch import bind as bind_lights
    from tracer.optics.surfaces.dispatch import bind

    with _BOUND_LOCK:
        entry = next((e for e in _BOUND if e[0] is sa and e[1] is mats and e[2] is lights), None)
    if entry is None:
        entry = [sa, mats, lights, bind(sa, mats), bind_lights(lights), None]
        with _BOUND_LOCK:
            _BOUND[:] = [entry, *_BOUND[:_BOUND_KEEP - 1]]
    if joins and entry[5] is None:
        from tracer.transport.through_flat import bind as bind_joins

        entry[5] = bind_joins(sa, entry[3])
    return entry[3], entry[4], entry[5]


def run_kernel(kernel_id: KernelId, scene: tuple, query: tuple, batch0: int, n_batches: int, size: int):
    """Run batches of the kernel `kernel_id` here: ``("forward", state)`` takes scene = (scene arrays,
    materials, lights) and query = (receiver arrays, sensor arrays, bins, seed); ``("backward",)`` takes
    scene = (scene arrays, materials, lights) and query = (query arrays, seed); ``("radiance",)`` takes the
    same scene and query = (view arrays, emitters, light paths, seed) (`tracer.transport.radiance`). Module-level,
    so a Dask worker runs it by import; the kernel is compiled once per process (numba's dispatcher and disk cache)."""
    sa, mats, lights = scene
    joins = kernel_id[0] == "radiance" and bool(query[2].flat[0])   # light tracing joins through flat glass
    mats, lights, join_at = _bound(sa, mats, lights, joins)
    if kernel_id[0] == "forward":
        from tracer.transport.forward import forward_kernel

        ra, sens, n_bins, seed = query
        return forward_kernel(kernel_id[1])(sa, ra, mats, lights, sens, n_bins, seed, batch0, n_batches, size)
    if kernel_id[0] == "backward":
        from tracer.transport.backward import backward_batches

        q, seed = query
        return backward_batches(sa, mats, lights, q, seed, batch0, n_batches, size)
    if kernel_id[0] == "radiance":
        from tracer.transport.radiance import radiance_batches

        views, emit, traced, seed = query
        if joins:   # the join's function's address in this process
            traced = traced._replace(join_at=join_at)
        return radiance_batches(sa, mats, lights, views, emit, traced, seed, batch0, n_batches, size)
    raise ValueError(f"unknown kernel {kernel_id!r}")


def _splits(batch0: int, n_batches: int, parts: int) -> list[tuple[int, int]]:
    """Contiguous (first batch, count) runs of `n_batches` batches over at most `parts` workers."""
    parts = max(1, min(n_batches, parts))
    bounds = np.linspace(0, n_batches, parts + 1).astype(int)
    return [(batch0 + int(lo), int(hi - lo)) for lo, hi in zip(bounds[:-1], bounds[1:], strict=True) if hi > lo]


def _join(parts: list) -> tuple[np.ndarray, np.ndarray]:
    if len(parts) == 1:
        return parts[0]
    return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])


class _Round:
    """One `FairPool.map` call: its results in order, the chunks not yet finished, the first error."""

    def __init__(self, n: int) -> None:
        self.results: list[Any] = [None] * n
        self.left = n
        self.error: BaseException | None = None
        self.done = threading.Event()


class FairPool:
    """Threads shared by every query of this process, each query's share of them alike, whatever its rounds' size.

    A round (`map`) is cut into chunks by its caller; an idle thread takes the next chunk of the owner (the calling
    thread: a query runs its rounds one after another on one thread) that has used the least thread time so far.
    An owner that arrives, or comes back after more than `GRACE` s, starts at the least time of the owners running
    now, so no credit and no debt carries over from an earlier query. A plain first-come queue handed the cores out a
    round at a time, and rounds grow with the batches done: a query that started a little ahead kept its lead, 3.7
    times the photons of its twin in one CI run (`tests/service/test_hardening.py`)."""

    GRACE = 0.5   # s between two rounds of one query

    def __init__(self, threads: int) -> None:
        self.threads = max(1, int(threads))
        self._cond = threading.Condition()
        self._waiting: dict[int, deque] = {}       # owner -> its chunks not started: (round, index, fn, args)
        self._running: dict[int, int] = {}         # owner -> its chunks on a thread now
        self._used: dict[int, float] = {}          # owner -> thread seconds its chunks took
        self._left_at: dict[int, float] = {}       # owner -> when it last had nothing waiting or running
        self._workers: list[threading.Thread] = []

    def map(self, fn, args: list[tuple]) -> list:
        """``[fn(*a) for a in args]``, run on the pool's threads, in order; the first error is raised."""
        owner = threading.get_ident()
        job = _Round(len(args))
        with self._cond:
            self._start_workers()
            self._join(owner)
            self._waiting.setdefault(owner, deque()).extend((job, i, fn, a) for i, a in enumerate(args))
            self._cond.notify_all()
        job.done.wait()
        if job.error is not None:
            raise job.error
        return job.results

    def _active(self, owner: int) -> bool:
        return bool(self._waiting.get(owner)) or self._running.get(owner, 0) > 0

    def _join(self, owner: int) -> None:
        if self._active(owner):
            return
        now = time.perf_counter()
        for other, left in list(self._left_at.items()):   # forget the owners gone for good
            if now - left > self.GRACE and not self._active(other):
                for table in (self._waiting, self._running, self._used, self._left_at):
                    table.pop(other, None)
        floor = min((self._used[o] for o in self._used if o != owner and self._active(o)), default=0.0)
        self._used[owner] = max(self._used.get(owner, floor), floor)

    def _next(self) -> tuple | None:
        owners = [o for o, chunks in self._waiting.items() if chunks]
        if not owners:
            return None
        owner = min(owners, key=lambda o: self._used[o])
        self._running[owner] = self._running.get(owner, 0) + 1
        return owner, self._waiting[owner].popleft()

    def _start_workers(self) -> None:
        while len(self._workers) < self.threads:
            worker = threading.Thread(target=self._work, name=f"lumenlink-batch-{len(self._workers)}", daemon=True)
            self._workers.append(worker)
            worker.start()

    def _work(self) -> None:
        while True:
            with self._cond:
                taken = self._next()
                while taken is None:
                    self._cond.wait()
                    taken = self._next()
            owner, (job, index, fn, args) = taken
            t = time.perf_counter()
            try:
                if job.error is None:
                    job.results[index] = fn(*args)
            except BaseException as exc:  # noqa: BLE001 - handed to the round's caller, who raises it
                job.error = exc
            with self._cond:
                self._used[owner] += time.perf_counter() - t
                self._running[owner] -= 1
                if not self._active(owner):
                    self._left_at[owner] = time.perf_counter()
                job.left -= 1
                if job.left == 0:
                    job.done.set()


class InProcess:
    """Batches on threads of this process (the embedded default): a round is cut into chunks of contiguous batches
    (`CHUNKS_PER_THREAD` for each of `numba.get_num_threads()` threads) that run on one `FairPool` shared by all
    queries. The kernels are serial and release the GIL (``nogil=True``): no numba threading layer, so concurrent
    queries share the cores chunk by chunk, and no parallel-loop wrapper to compile (9 s of a cold start)."""

    name = "in-process"
    CHUNKS_PER_THREAD = 4   # a chunk of the largest round (128 batches) is about 0.15 s on this machine
    _pool: FairPool | None = None
    _pool_lock = threading.Lock()

    def __init__(self, shape: BatchShape = CPU_SHAPE) -> None:
        self.shape = shape   # another backend's shape: that backend's very batches, here (tests, a fallback)

    @classmethod
    def pool(cls) -> FairPool:
        with cls._pool_lock:
            if cls._pool is None:
                cls._pool = FairPool(numba.config.NUMBA_NUM_THREADS)
            return cls._pool

    def run(self, kernel_id: KernelId, scene: Shipment, query: Shipment, batch0: int, n_batches: int, size: int):
        threads = numba.get_num_threads()
        if threads == 1:
            return run_kernel(kernel_id, scene.parts, query.parts, batch0, n_batches, size)
        chunks = _splits(batch0, n_batches, threads * self.CHUNKS_PER_THREAD)
        return _join(self.pool().map(run_kernel, [(kernel_id, scene.parts, query.parts, b0, nb, size)
                                                  for b0, nb in chunks]))

    def describe(self) -> dict[str, Any]:
        return {"name": self.name, "threads": int(numba.get_num_threads())}


IN_PROCESS = InProcess()


class DaskBackend:
    """Batches as tasks on the Dask cluster whose scheduler listens at `address` (``tcp://host:port``).

    Connects on first use and again after the scheduler went away. `connect_timeout` (s) bounds every
    wait for the scheduler; `stall_timeout` (s) is how long a round may make no progress while the
    scheduler is unreachable or has no workers before `BackendUnavailable`."""

    name = "dask"
    shape = CPU_SHAPE
    KEEP_SHIPMENTS = 16      # snapshots and queries kept scattered on the workers, most recent first …
    KEEP_BYTES = 2 << 30     # … and at most this many bytes together (the latest two, a query's scene and receivers,
                             # stay whatever their size)
    RESEND_TRIES = 3         # a round whose data was lost with a worker is sent again this often
    THREADS_TTL = 1.0        # s: how long the cluster's thread count is taken as known

    def __init__(self, address: str, connect_timeout: float = 10.0, stall_timeout: float = 30.0) -> None:
        if not isinstance(address, str) or "://" not in address:
            raise ValueError(f"a Dask scheduler address looks like tcp://host:8786, got {address!r}")
        self.address = address
        self.connect_timeout = float(connect_timeout)
        self.stall_timeout = float(stall_timeout)
        self._client: Any = None
        self._lock = threading.Lock()
        self._shipped: OrderedDict[str, tuple[Any, int]] = OrderedDict()   # content key -> (Future, bytes)
        self._threads_seen: tuple[float, int] = (0.0, 0)        # (when, worker threads then)

    # -- connection -----------------------------------------------------------------------------

    def client(self) -> Any:
        """The connected `distributed.Client`; `BackendUnavailable` if the scheduler does not answer."""
        from distributed import Client

        with self._lock:
            if self._client is not None and self._client.status == "running":
                return self._client
            self._drop_client()
            try:
                self._client = Client(self.address, timeout=self.connect_timeout, set_as_default=False)
            except (OSError, TimeoutError) as exc:
                raise BackendUnavailable(f"the Dask scheduler at {self.address} does not answer ({exc}); start "
                                         f"it, or serve without --dask to compute in this process") from None
            return self._client

    def _drop_client(self) -> None:
        self._shipped.clear()
        if self._client is not None:
            client, self._client = self._client, None
            try:
                client.close(timeout=2)
            except Exception:  # noqa: BLE001 - a broken connection may fail to close; it is dropped either way
                log.debug("closing a broken Dask client failed", exc_info=True)

    def close(self) -> None:
        with self._lock:
            self._drop_client()

    def workers(self) -> dict[str, int]:
        """{worker address: threads} of the cluster now."""
        info = self.client().scheduler_info(n_workers=-1)
        return {addr: int(w.get("nthreads", 1)) for addr, w in info.get("workers", {}).items()}

    def describe(self) -> dict[str, Any]:
        try:
            workers = self.workers()
        except BackendUnavailable:
            workers = {}
        return {"name": self.name, "address": self.address, "workers": len(workers),
                "threads": int(sum(workers.values()))}

    # -- data -----------------------------------------------------------------------------------

    def _ship(self, client: Any, shipment: Shipment) -> Any:
        """The future of `shipment` on the workers, scattered to every worker once per content key."""
        key = shipment.key
        with self._lock:
            held = self._shipped.get(key)
            if held is not None and held[0].status == "finished":
                self._shipped.move_to_end(key)
                return held[0]
        name = f"lumenlink-shipment-{key}"
        future = client.scatter({name: shipment.parts}, broadcast=True, timeout=self.connect_timeout)[name]
        with self._lock:
            self._shipped[key] = (future, shipment.nbytes)
            self._shipped.move_to_end(key)
            while len(self._shipped) > 2 and (len(self._shipped) > self.KEEP_SHIPMENTS or
                                              sum(n for _, n in self._shipped.values()) > self.KEEP_BYTES):
                self._shipped.popitem(last=False)   # the oldest: its data leave the workers once no task needs them
        return future

    def _forget(self, *shipments: Shipment) -> None:
        with self._lock:
            for s in shipments:
                self._shipped.pop(s.key, None)

    # -- batches --------------------------------------------------------------------------------

    def run(self, kernel_id: KernelId, scene: Shipment, query: Shipment, batch0: int, n_batches: int, size: int):
        for attempt in range(self.RESEND_TRIES):
            client = self.client()
            threads = self._threads_or_wait(client)
            try:
                scene_f, query_f = self._ship(client, scene), self._ship(client, query)
                token = uuid.uuid4().hex
                futures = [client.submit(run_kernel, kernel_id, scene_f, query_f, b0, nb, size, pure=False,
                                         key=f"lumenlink-{kernel_id[0]}-{token}-{b0}")
                           for b0, nb in _splits(batch0, n_batches, threads)]
                return _join(self._gather(client, futures))
            except _LostData as exc:
                # a worker died holding the only copy of something, or the scheduler restarted: send again
                log.warning("Dask round lost (%s); sending the data again (attempt %d)", exc, attempt + 1)
                self._forget(scene, query)
            except OSError as exc:
                self.close()
                raise BackendUnavailable(f"the Dask scheduler at {self.address} went away ({exc})") from None
        raise BackendUnavailable(f"the Dask cluster at {self.address} lost this round's data "
                                 f"{self.RESEND_TRIES} times; is a worker restarting in a loop?")

    def _threads_or_wait(self, client: Any) -> int:
        """Worker threads now (asked of the scheduler at most every `THREADS_TTL` seconds: a round trip of its
        own); waits up to `stall_timeout` for a first worker."""
        seen, threads = self._threads_seen
        if threads > 0 and time.monotonic() - seen < self.THREADS_TTL:
            return threads
        deadline = time.monotonic() + self.stall_timeout
        while True:
            threads = sum(int(w.get("nthreads", 1)) for w in client.scheduler_info(n_workers=-1)
                          .get("workers", {}).values())
            self._threads_seen = (time.monotonic(), threads)
            if threads > 0:
                return threads
            if time.monotonic() >= deadline:
                raise BackendUnavailable(f"the Dask scheduler at {self.address} has no workers "
                                         f"(waited {self.stall_timeout:g} s); start some with "
                                         f"`dask worker {self.address}`")
            time.sleep(0.2)

    def _gather(self, client: Any, futures: list) -> list:
        """The results of `futures` in order; `BackendUnavailable` when the scheduler stays unreachable (or the
        cluster workerless) for `stall_timeout` seconds, `_LostData` when a task's input went with a worker."""
        from distributed import KilledWorker
        from distributed.client import FutureCancelledError

        out = []
        stalled_since: float | None = None
        for f in futures:
            while True:
                try:
                    out.append(f.result(timeout=0.5))
                    break
                except TimeoutError:
                    pass
                except (FutureCancelledError, KilledWorker) as exc:
                    raise _LostData(f"{type(exc).__name__}: {exc}") from None
                healthy = client.status == "running" and bool(client.scheduler_info().get("workers"))
                if healthy:
                    stalled_since = None
                elif stalled_since is None:
                    stalled_since = time.monotonic()
                elif time.monotonic() - stalled_since > self.stall_timeout:
                    for g in futures:
                        g.cancel()
                    self.close()
                    raise BackendUnavailable(f"the Dask cluster at {self.address} made no progress for "
                                             f"{self.stall_timeout:g} s (scheduler gone or no workers)")
        return out


class _LostData(RuntimeError):
    """A task's input went away with a worker (internal: the round is sent again)."""


def device_of(described: dict[str, Any] | None) -> str | None:
    """The answer's ``device`` (docs/DESIGN.md "On a GPU") from a backend's `describe()`: where the photon batches
    ran, ``"cuda:0 NVIDIA H100 80GB HBM3"`` (`tracer.gpu.backend.CudaBackend`), ``"cpu:2 threads"``, or
    ``"cpu:4 threads on 2 dask workers"``."""
    if not described:
        return None
    if described.get("name") == "cuda":
        return str(described.get("device", "cuda"))
    where = f"cpu:{int(described.get('threads', 0))} threads"
    if described.get("name") == "dask":
        where += f" on {int(described.get('workers', 0))} dask workers"
    return where


def is_backend(obj: Any) -> bool:
    """Whether `obj` is a backend: `InProcess`, `DaskBackend`, or `tracer.gpu.backend.CudaBackend` (looked up only
    where that module was imported, which a CudaBackend needs: a CPU-only process never imports numba-cuda)."""
    if isinstance(obj, InProcess | DaskBackend):
        return True
    gpu = sys.modules.get("tracer.gpu.backend")
    return gpu is not None and isinstance(obj, gpu.CudaBackend)


def backend_for(address: str | None) -> InProcess | DaskBackend:
    """The in-process backend, or a Dask one for a scheduler address (``LUMENLINK_DASK_SCHEDULER``)."""
    return IN_PROCESS if not address else DaskBackend(address)
