"""`tracer.backends.FairPool`: the threads every query of a process shares, each query's share of them alike."""

from __future__ import annotations

import functools
import threading
import time

import pytest

from tracer.backends import FairPool, _splits

BATCH_S = 0.004   # s a batch "traces" here: a sleep, which frees the GIL as the kernels do


def _batches(log: list, name: str, b0: int, nb: int) -> list[int]:
    time.sleep(BATCH_S * nb)
    log.append((time.perf_counter(), name, nb))   # when this chunk of the query's round ended
    return list(range(b0, b0 + nb))


def _query(pool: FairPool, seconds: float, log: list, name: str, span: dict) -> None:
    """A time-bound query as `tracer.transport.rounds.loop` runs one: rounds of 8 batches at first, then a quarter
    of the batches done so far (at most 128), each cut into 4 chunks a thread, until `seconds` have passed."""
    t0, batches = time.perf_counter(), 0
    while time.perf_counter() - t0 < seconds:
        nb = min(128, max(8, batches // 4))
        parts = pool.map(functools.partial(_batches, log, name), _splits(batches, nb, 8))
        assert sum(parts, []) == list(range(batches, batches + nb))
        batches += nb
    span[name] = (t0, time.perf_counter())


def test_two_queries_at_once_get_the_threads_alike_though_one_started_ahead():
    """Query A starts 0.4 s before its twin B, long enough for its rounds to grow to several times B's; each runs for
    its own 2 s. Chunk by chunk, the owner that has used the least thread time goes next, so while both run they
    get the threads alike: over that time (from 0.05 s after B's start, when the chunks already running have ended,
    to A's end) their batches are within 1.4x of each other (1.13-1.18x with three busy loops beside the test on two
    cores: a query between two of its rounds has no chunk waiting, and the other's chunk then runs). A first-come
    queue hands the threads out round by round, and A's larger rounds kept their lead: 752 batches to B's 69 here,
    and in a CI run of the service 3.7 times B's photons."""
    pool, log, span = FairPool(2), [], {}
    a = threading.Thread(target=_query, args=(pool, 2.0, log, "A", span))
    b = threading.Thread(target=_query, args=(pool, 2.0, log, "B", span))
    a.start()
    time.sleep(0.4)
    b.start()
    a.join()
    b.join()
    lo, hi = span["B"][0] + 0.05, span["A"][1]
    done = {name: sum(nb for t, who, nb in log if who == name and lo <= t <= hi) for name in "AB"}
    assert min(done.values()) > 50, done
    assert max(done.values()) <= 1.4 * min(done.values()), done


def test_a_round_answers_in_order_and_its_error_reaches_its_caller_only():
    pool = FairPool(2)
    assert pool.map(functools.partial(_batches, [], "Q"), [(0, 1), (1, 2), (3, 1)]) == [[0], [1, 2], [3]]

    def fails(i):
        if i == 2:
            raise ValueError("chunk 2 failed")
        return i

    with pytest.raises(ValueError, match="chunk 2 failed"):
        pool.map(fails, [(i,) for i in range(5)])
    assert pool.map(fails, [(0,), (1,)]) == [0, 1]   # the pool goes on
