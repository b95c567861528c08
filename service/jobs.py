"""In-process simulation jobs: a few worker threads, a bounded queue, progress and cancellation.

A job wraps one long query (an illuminance query or a grid simulation). The work function gets two
callbacks that match the light transport's own (docs/CONTRACTS.md): ``progress(photons,
worst_relative_error, seconds)``, called between photon batches, and ``cancel()``, which turns
truthy once somebody asked to stop. The runner keeps the latest progress, estimates the time left
from the budget, and keeps the result (or the error) after the job ends.

Why threads in the service process: the kernels are numba code that spends its time outside the
interpreter, a query has a hard budget (photons, seconds), and the embedded default must run
with nothing else to start. The queue is bounded so that a flood of submissions is refused
(`QueueFull`) instead of growing memory without limit; finished jobs are forgotten oldest first
beyond ``keep_finished``.

Workers are daemon threads: a process that exits does not wait for a query to finish.
"""

from __future__ import annotations

import math
import queue
import threading
import time
import uuid
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

from service.errors import ServiceError
from tracer.transport.query import Budget

ProgressFn = Callable[[int, float, float], None]
CancelFn = Callable[[], bool]
WorkFn = Callable[[ProgressFn, CancelFn], dict[str, Any]]


class JobStatus(StrEnum):
    """Life of a job: queued → running → one of succeeded, failed, cancelled."""

    QUEUED = "queued"
    RUNNING = "running"
    SUCCEEDED = "succeeded"
    FAILED = "failed"
    CANCELLED = "cancelled"

    @property
    def finished(self) -> bool:
        return self in (JobStatus.SUCCEEDED, JobStatus.FAILED, JobStatus.CANCELLED)


class JobError(ServiceError):
    """Root of the job runner's errors (under the service's one root, `ServiceError`)."""


class JobNotFound(JobError, LookupError):
    """No job with that id (never existed, or forgotten after ``keep_finished`` newer jobs ended)."""

    status = 404
    title = "Not found"


class QueueFull(JobError, RuntimeError):
    """The queue already holds ``max_queued`` jobs waiting for a worker."""

    status = 503
    title = "Service unavailable"


def estimate_seconds_left(photons: int, worst_relative_error: float, seconds: float, budget: Budget,
                          rate: float | None = None) -> float | None:
    """Seconds until the first stopping rule is expected to fire, or None if nothing can tell yet.

    The standard error of a Monte Carlo mean falls as 1/√N, so reaching ``target`` from the current
    worst relative error ``r`` after ``N`` photons takes ``N·(r/target)²`` photons in all; the
    photon rate so far turns photons into seconds. The answer is the smallest of that, the time
    to ``max_photons`` and the time to ``max_seconds``.

    Parameters
    ----------
    photons : int
        Photons traced so far.
    worst_relative_error : float
        Largest relative standard error over the values so far (inf or NaN while unknown).
    seconds : float
        Time spent so far, s.
    budget : Budget
        The job's stopping rules.
    rate : float, optional
        Photons per second of tracing; default photons / seconds (which counts any compiling in `seconds` as
        slow tracing: `JobRunner` passes the rate since the first progress report instead).

    Returns
    -------
    float or None
        Estimated seconds left (>= 0).
    """
    candidates: list[float] = []
    if budget.max_seconds is not None:
        candidates.append(max(budget.max_seconds - seconds, 0.0))
    if rate is None:
        rate = photons / seconds if photons > 0 and seconds > 0 else None
    if rate is not None and rate > 0:
        if budget.max_photons is not None:
            candidates.append(max(budget.max_photons - photons, 0) / rate)
        target = budget.target
        if target is not None and math.isfinite(worst_relative_error) and worst_relative_error >= 0:
            needed = photons * (worst_relative_error / target) ** 2
            candidates.append(max(needed - photons, 0.0) / rate)
    return min(candidates) if candidates else None


@dataclass
class Job:
    """One submitted job; read it through `snapshot()` (fields change under the runner's lock)."""

    id: str
    kind: str
    scene_id: str
    revision: int
    budget: Budget
    work: WorkFn
    meta: dict[str, Any] = field(default_factory=dict)
    status: JobStatus = JobStatus.QUEUED
    created_at: float = field(default_factory=time.time)
    started_at: float | None = None
    finished_at: float | None = None
    photons: int = 0
    worst_relative_error: float | None = None
    seconds: float = 0.0
    seconds_left: float | None = None
    compile_seconds: float | None = None
    result: dict[str, Any] | None = None
    error: str | None = None
    detail: dict[str, Any] = field(default_factory=dict)   # a job's own progress fields (a pack's iteration, ...)
    cancel_event: threading.Event = field(default_factory=threading.Event)

    def snapshot(self) -> dict[str, Any]:
        """A JSON-ready copy of the job's state (the `result` dict is shared, not copied)."""
        worst = self.worst_relative_error
        return {
            "id": self.id,
            "kind": self.kind,
            "scene_id": self.scene_id,
            "revision": self.revision,
            "status": self.status.value,
            "cancel_requested": self.cancel_event.is_set(),
            "created_at": self.created_at,
            "started_at": self.started_at,
            "finished_at": self.finished_at,
            "progress": {
                "photons": self.photons,
                "worst_relative_error": worst if worst is not None and math.isfinite(worst) else None,
                "seconds": self.seconds,
                "seconds_left": self.seconds_left,
                "compile_seconds": self.compile_seconds,
                **self.detail,
            },
            "result": self.result,
            "error": self.error,
            **self.meta,
        }


class JobRunner:
    """A pool of worker threads fed from a bounded queue.

    Parameters
    ----------
    workers : int
        Worker threads (>= 1). Each runs one job at a time; a job's kernels may use more cores.
    max_queued : int
        Jobs that may wait for a worker (>= 1); `submit` raises `QueueFull` beyond it.
    keep_finished : int
        Finished jobs remembered for `get` (>= 1), oldest forgotten first.
    """

    def __init__(self, workers: int = 1, max_queued: int = 16, keep_finished: int = 256) -> None:
        for name, value in (("workers", workers), ("max_queued", max_queued), ("keep_finished", keep_finished)):
            if not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
        self._queue: queue.Queue[Job | None] = queue.Queue(maxsize=max_queued)
        self._jobs: OrderedDict[str, Job] = OrderedDict()
        self._lock = threading.Lock()
        self._keep_finished = keep_finished
        self._closed = False
        self._threads = [
            threading.Thread(target=self._worker, name=f"lumenlink-job-{k}", daemon=True) for k in range(workers)
        ]
        for t in self._threads:
            t.start()

    # -- public API -------------------------------------------------------------------------

    def submit(self, kind: str, scene_id: str, revision: int, work: WorkFn, budget: Budget | None = None,
               meta: dict[str, Any] | None = None) -> Job:
        """Queue ``work(progress, cancel) -> result dict``; returns the job (status queued).

        Raises
        ------
        QueueFull
            When ``max_queued`` jobs are already waiting (or the runner is shut down).
        """
        job = Job(id=uuid.uuid4().hex, kind=kind, scene_id=scene_id, revision=revision,
                  budget=budget or Budget(), work=work, meta=dict(meta or {}))
        with self._lock:
            if self._closed:
                raise QueueFull("the job runner is shut down")
            try:
                self._queue.put_nowait(job)
            except queue.Full:
                raise QueueFull(f"{self._queue.maxsize} jobs are already waiting; try again later") from None
            self._jobs[job.id] = job
        return job

    def get(self, job_id: str) -> dict[str, Any]:
        """The job's current state (see `Job.snapshot`); raises `JobNotFound`."""
        with self._lock:
            job = self._jobs.get(job_id)
            if job is None:
                raise JobNotFound(f"no job {job_id!r}")
            return job.snapshot()

    def cancel_scene(self, scene_id: str) -> int:
        """Cancel every unfinished job of a scene (it was deleted); returns how many were asked to stop."""
        with self._lock:
            ids = [j.id for j in self._jobs.values() if j.scene_id == scene_id and not j.status.finished]
        for job_id in ids:
            self.cancel(job_id)
        return len(ids)

    def cancel(self, job_id: str) -> dict[str, Any]:
        """Ask a job to stop; a queued job never starts, a running one stops after its current batch.

        Cancelling a finished job changes nothing. Returns the job's state after the request;
        raises `JobNotFound`.
        """
        with self._lock:
            job = self._jobs.get(job_id)
            if job is None:
                raise JobNotFound(f"no job {job_id!r}")
            if not job.status.finished:
                job.cancel_event.set()
                if job.status is JobStatus.QUEUED:
                    self._finish(job, JobStatus.CANCELLED)
            return job.snapshot()

    def jobs(self) -> list[dict[str, Any]]:
        """States of every remembered job, oldest first."""
        with self._lock:
            return [j.snapshot() for j in self._jobs.values()]

    def shutdown(self, wait: float = 0.0) -> None:
        """Cancel every job and stop the workers, waiting up to ``wait`` seconds for them."""
        with self._lock:
            self._closed = True
            for job in self._jobs.values():
                if not job.status.finished:
                    job.cancel_event.set()
                    if job.status is JobStatus.QUEUED:
                        self._finish(job, JobStatus.CANCELLED)
        for _ in self._threads:
            try:
                self._queue.put(None, timeout=max(wait, 0.01))
            except queue.Full:
                break
        deadline = time.monotonic() + wait
        for t in self._threads:
            t.join(timeout=max(deadline - time.monotonic(), 0.0))

    # -- internals --------------------------------------------------------------------------

    def _finish(self, job: Job, status: JobStatus) -> None:
        # caller holds the lock
        job.status = status
        job.finished_at = time.time()
        if status is JobStatus.SUCCEEDED:
            job.seconds_left = 0.0
        else:
            job.seconds_left = None
        finished = [j for j in self._jobs.values() if j.status.finished]
        for old in finished[: max(len(finished) - self._keep_finished, 0)]:
            del self._jobs[old.id]

    def _worker(self) -> None:
        while True:
            job = self._queue.get()
            if job is None:
                return
            with self._lock:
                if job.status is not JobStatus.QUEUED:  # cancelled while waiting
                    continue
                job.status = JobStatus.RUNNING
                job.started_at = time.time()
            self._run(job)

    def _run(self, job: Job) -> None:
        first: list[tuple[int, float]] = []   # (photons, seconds) at the first report: compiling lies before it

        def progress(photons: int, worst_relative_error: float, seconds: float, **detail: Any) -> None:
            if detail:   # a job's own fields, beside the photons (a pack: iteration, uniformity ± error)
                with self._lock:
                    job.detail.update(detail)
            if photons == 0:   # the report before the first round: the seconds spent compiling (or loading)
                with self._lock:
                    job.compile_seconds = float(seconds)
                    job.seconds = float(seconds)
                return
            # the tracing rate since the first report, so that the seconds a first query spends compiling
            # (a minute on a fresh install) do not read as slow tracing and make seconds_left drift down
            if not first:
                first.append((int(photons), float(seconds)))
            p0, s0 = first[0]
            rate = (photons - p0) / (seconds - s0) if photons > p0 and seconds > s0 else None
            left = estimate_seconds_left(int(photons), float(worst_relative_error), float(seconds), job.budget,
                                         rate)
            with self._lock:
                job.photons = int(photons)
                job.worst_relative_error = float(worst_relative_error)
                job.seconds = float(seconds)
                job.seconds_left = left

        def cancel() -> bool:
            return job.cancel_event.is_set()

        try:
            result = job.work(progress, cancel)
        except Exception as exc:  # a job's failure is reported through GET /jobs, never raised into the worker
            with self._lock:
                job.error = f"{type(exc).__name__}: {exc}"
                self._finish(job, JobStatus.FAILED)
            return
        with self._lock:
            job.result = result
            if isinstance(result, dict):
                job.photons = int(result.get("photons", job.photons))
                job.seconds = float(result.get("seconds", job.seconds))
            self._finish(job, JobStatus.CANCELLED if job.cancel_event.is_set() else JobStatus.SUCCEEDED)
