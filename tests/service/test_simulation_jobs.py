"""The in-process job runner: lifecycle, progress, cancellation, bounded queue, time-left estimate.

The work functions here are tiny stand-ins that call the same progress/cancel callbacks as the
light transport; they exist only inside these tests (the endpoints run the real simulation).
"""

from __future__ import annotations

import math
import threading
import time

import pytest

from service.jobs import JobNotFound, JobRunner, JobStatus, QueueFull, estimate_seconds_left
from tracer.transport.query import Budget


def wait_for(runner: JobRunner, job_id: str, predicate, timeout: float = 10.0) -> dict:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        state = runner.get(job_id)
        if predicate(state):
            return state
        time.sleep(0.005)
    raise AssertionError(f"job {job_id} never reached the expected state: {runner.get(job_id)}")


def batches_until_cancelled(gate: threading.Event, reported: threading.Event):
    """A stand-in for a long query: reports progress per 'batch' until cancelled."""

    def work(progress, cancel):
        photons = 0
        while not cancel():
            photons += 1000
            progress(photons, 1.0 / math.sqrt(photons), photons * 1e-6)
            reported.set()
            gate.wait(0.01)
        return {"photons": photons, "seconds": photons * 1e-6, "stop_reason": "cancelled"}

    return work


@pytest.fixture
def runner():
    r = JobRunner(workers=1, max_queued=2, keep_finished=3)
    yield r
    r.shutdown(wait=2.0)


def test_job_runs_to_success_and_keeps_its_result(runner: JobRunner) -> None:
    def work(progress, cancel):
        progress(500, 0.1, 0.5)
        return {"lux": [1.0], "photons": 1000, "seconds": 1.0}

    job = runner.submit("illuminance", "s1", 3, work)
    state = wait_for(runner, job.id, lambda s: s["status"] == "succeeded")
    assert state["result"]["lux"] == [1.0]
    assert state["progress"]["photons"] == 1000
    assert state["progress"]["seconds_left"] == 0.0
    assert state["revision"] == 3 and state["scene_id"] == "s1"
    assert state["started_at"] <= state["finished_at"]


def test_failure_is_reported_not_raised(runner: JobRunner) -> None:
    def work(progress, cancel):
        raise ValueError("scene has no light")

    job = runner.submit("illuminance", "s1", 0, work)
    state = wait_for(runner, job.id, lambda s: s["status"] == "failed")
    assert "scene has no light" in state["error"] and state["result"] is None
    # the worker survives a failing job
    ok = runner.submit("illuminance", "s1", 0, lambda p, c: {"photons": 1, "seconds": 0.0})
    wait_for(runner, ok.id, lambda s: s["status"] == "succeeded")


def test_cancel_running_job_stops_it_between_batches(runner: JobRunner) -> None:
    gate, reported = threading.Event(), threading.Event()
    job = runner.submit("grid", "s1", 1, batches_until_cancelled(gate, reported), Budget(max_photons=10**9))
    assert reported.wait(5.0)
    running = runner.get(job.id)
    assert running["status"] == "running" and running["progress"]["photons"] > 0
    assert running["progress"]["worst_relative_error"] > 0
    runner.cancel(job.id)
    state = wait_for(runner, job.id, lambda s: s["status"] == "cancelled")
    assert state["cancel_requested"] and state["result"]["stop_reason"] == "cancelled"


def test_cancel_queued_job_never_starts(runner: JobRunner) -> None:
    gate, reported = threading.Event(), threading.Event()
    blocker = runner.submit("grid", "s1", 1, batches_until_cancelled(gate, reported))
    assert reported.wait(5.0)
    started = threading.Event()

    def work(progress, cancel):
        started.set()
        return {}

    queued = runner.submit("grid", "s1", 1, work)
    assert runner.get(queued.id)["status"] == "queued"
    assert runner.cancel(queued.id)["status"] == "cancelled"
    runner.cancel(blocker.id)
    wait_for(runner, blocker.id, lambda s: s["status"] == "cancelled")
    time.sleep(0.05)
    assert not started.is_set()
    assert runner.get(queued.id)["status"] == "cancelled"


def test_cancel_finished_job_changes_nothing(runner: JobRunner) -> None:
    job = runner.submit("grid", "s1", 1, lambda p, c: {"photons": 5, "seconds": 0.0})
    wait_for(runner, job.id, lambda s: s["status"] == "succeeded")
    assert runner.cancel(job.id)["status"] == "succeeded"


def test_queue_is_bounded(runner: JobRunner) -> None:
    gate, reported = threading.Event(), threading.Event()
    blocker = runner.submit("grid", "s1", 1, batches_until_cancelled(gate, reported))
    assert reported.wait(5.0)  # the worker is busy; the queue (max 2) is empty
    waiting = [runner.submit("grid", "s1", 1, lambda p, c: {}) for _ in range(2)]
    with pytest.raises(QueueFull):
        runner.submit("grid", "s1", 1, lambda p, c: {})
    assert len(runner.jobs()) == 3  # the refused one left no trace
    runner.cancel(blocker.id)
    for job in waiting:
        wait_for(runner, job.id, lambda s: s["status"] == "succeeded")


def test_unknown_job_and_forgetting_oldest_finished(runner: JobRunner) -> None:
    with pytest.raises(JobNotFound):
        runner.get("nope")
    with pytest.raises(JobNotFound):
        runner.cancel("nope")
    ids = []
    for _ in range(5):
        job = runner.submit("grid", "s1", 1, lambda p, c: {})
        wait_for(runner, job.id, lambda s: s["status"] == "succeeded")
        ids.append(job.id)
    kept = [j["id"] for j in runner.jobs()]
    assert kept == ids[-3:]
    with pytest.raises(JobNotFound):
        runner.get(ids[0])


def test_shutdown_refuses_new_jobs_and_cancels_running() -> None:
    r = JobRunner(workers=1, max_queued=1)
    gate, reported = threading.Event(), threading.Event()
    job = r.submit("grid", "s1", 1, batches_until_cancelled(gate, reported))
    assert reported.wait(5.0)
    r.shutdown(wait=5.0)
    assert r.get(job.id)["status"] == "cancelled"
    with pytest.raises(QueueFull):
        r.submit("grid", "s1", 1, lambda p, c: {})


@pytest.mark.parametrize("kwargs", [{"workers": 0}, {"max_queued": 0}, {"keep_finished": -1}, {"workers": 1.5}])
def test_runner_rejects_bad_sizes(kwargs) -> None:
    with pytest.raises(ValueError):
        JobRunner(**kwargs)


def test_seconds_left_follows_inverse_square_root_law() -> None:
    # 1e4 photons in 2 s gave 4 % error; 1 % needs 16× the photons, i.e. 15 × 2 s more.
    left = estimate_seconds_left(10_000, 0.04, 2.0, Budget(target=0.01))
    assert left == pytest.approx(30.0)
    # the smallest of the stopping rules wins
    assert estimate_seconds_left(10_000, 0.04, 2.0, Budget(0.01, max_seconds=12.0)) == pytest.approx(10.0)
    assert estimate_seconds_left(10_000, 0.04, 2.0, Budget(0.01, max_photons=20_000)) == pytest.approx(2.0)
    # already below target: nothing left; unknown error and no other rule: no estimate
    assert estimate_seconds_left(10_000, 0.005, 2.0, Budget(0.01)) == 0.0
    assert estimate_seconds_left(10_000, math.inf, 2.0, Budget(0.01)) is None
    assert estimate_seconds_left(0, math.nan, 0.0, Budget(max_seconds=5.0)) == 5.0
    assert JobStatus.CANCELLED.finished and not JobStatus.RUNNING.finished


def test_concurrent_query_slots_come_from_the_settings() -> None:
    """`LUMENLINK_MAX_CONCURRENT_QUERIES` sync queries run at once; the next waits
    `LUMENLINK_QUEUE_WAIT_SECONDS`, then gets 503 saying how many run."""
    from types import SimpleNamespace

    from service.config import Settings
    from service.simulation import Limits, SimulationHub, Unavailable

    settings = Settings(max_concurrent_queries=1, queue_wait_seconds=0.05)
    hub = SimulationHub(SimpleNamespace(subscribe=lambda listener: None), Limits.from_settings(settings))
    with hub.slot():
        with pytest.raises(Unavailable, match="1 queries are running"):
            with hub.slot():
                pass
    with hub.slot():   # freed again
        pass


def test_seconds_left_holds_still_when_the_first_round_waited_for_the_compiler() -> None:
    """A job that spent 30 s compiling before its first round, then traces 100k photons/s with an error falling as
    1/√N toward a 0.5 % target: every report's elapsed + seconds_left names the same end (it used to fall from
    ~600 s toward the truth as the compile time was spread over more photons)."""
    reports = [(n, 0.08 * (100_000 / n) ** 0.5, 30.0 + n / 100_000) for n in (100_000, 200_000, 400_000, 800_000)]
    go, seen = threading.Event(), threading.Event()
    ends, compiled = [], []
    runner = JobRunner()

    def work(progress, cancel):
        go.wait(10)
        progress(0, math.inf, 29.5)   # before the first round: what compiling took
        compiled.append(runner.get(job.id)["progress"]["compile_seconds"])
        for n, err, seconds in reports:
            progress(n, err, seconds)
            ends.append(runner.get(job.id)["progress"]["seconds_left"] + seconds)
        seen.set()
        return {}

    job = runner.submit("grid", "s1", 1, work, Budget(target=0.005))
    go.set()
    assert seen.wait(10)
    true_end = 30.0 + 100_000 * (0.08 / 0.005) ** 2 / 100_000   # 30 s compiling + 256 s tracing
    assert ends[0] is not None and all(e == pytest.approx(true_end, rel=1e-6) for e in ends[1:])
    assert compiled == [29.5] and runner.get(job.id)["progress"]["compile_seconds"] == 29.5
    old = [estimate_seconds_left(n, e, s, Budget(0.005)) + s for n, e, s in reports]
    assert old[0] > 2 * true_end   # what it said before: compiling read as slow tracing
    runner.shutdown()


def test_one_budget_and_one_default_from_the_route_to_the_rounds() -> None:
    """Issue 55: the service's jobs and the tracer's rounds stop by the same `Budget`, and a query that states no time
    runs under the same default in both (capped by the service's limit); a stated budget passes as stated."""
    from service import jobs
    from service.simulation import Limits, resolve_budget
    from tracer.transport.query import DEFAULT_MAX_SECONDS, check_budget

    assert jobs.Budget is Budget
    limits = Limits(max_points=100, max_photons=10**9, max_seconds=600.0)
    assert resolve_budget(limits, None, None, None) == Budget(None, DEFAULT_MAX_SECONDS, 10**9, "worst")
    assert check_budget(None, None, None).stop_rules() == Budget(None, DEFAULT_MAX_SECONDS, None, "worst")
    assert resolve_budget(Limits(100, 10**9, 20.0), None, None, None).max_seconds == 20.0   # the limit caps it
    assert resolve_budget(limits, 0.02, 5.0, 1000, "lit") == Budget(0.02, 5.0, 1000, "lit")
