"""`tracer.backends.FairPool`: the threads every query of a process shares, each query's share of them alike."""

from __future__ import annotations

import threading
import time

import pytest

from tracer.backends import FairPool, _splits

BATCH_S = 0.004   # s a batch "traces" here: a sleep, which frees the GIL as the kernels do


def _batches(b0: int, nb: int) -> list[int]:
    time.sleep(BATCH_S * nb)
    return list(range(b0, b0 + nb))


def _query(pool: FairPool, seconds: float, done: dict, name: str) -> None:
    """A time-bound query as `tracer.transport.rounds.loop` runs one: rounds of 8 batches at first, then a quarter
    of the batches done so far (at most 128), each cut into 4 chunks a thread, until `seconds` have passed."""
    t0, batches = time.perf_counter(), 0
    while time.perf_counter() - t0 < seconds:
        nb = min(128, max(8, batches // 4))
        parts = pool.map(_batches, _splits(batches, nb, 8))
        assert sum(parts, []) == list(range(batches, batches + nb))
        batches += nb
    done[name] = batches


def test_two_queries_at_once_get_the_threads_alike_though_one_started_ahead():
    """Query A starts 0.4 s before its twin B, long enough for its rounds to grow to several times B's; each runs for
    its own 2 s. Chunk by chunk, the owner that has used the least thread time goes next, so from B's start on they
    share alike and each ends with about as many batches (A's head start is given back by B's tail). A first-come
    queue gives the cores out round by round: A kept its lead, 3.7 times B's photons in a CI run of the service."""
    pool, done = FairPool(2), {}
    a = threading.Thread(target=_query, args=(pool, 2.0, done, "A"))
    b = threading.Thread(target=_query, args=(pool, 2.0, done, "B"))
    a.start()
    time.sleep(0.4)
    b.start()
    a.join()
    b.join()
    assert max(done.values()) <= 1.3 * min(done.values()), done


def test_a_round_answers_in_order_and_its_error_reaches_its_caller_only():
    pool = FairPool(2)
    assert pool.map(_batches, [(0, 1), (1, 2), (3, 1)]) == [[0], [1, 2], [3]]

    def fails(i):
        if i == 2:
            raise ValueError("chunk 2 failed")
        return i

    with pytest.raises(ValueError, match="chunk 2 failed"):
        pool.map(fails, [(i,) for i in range(5)])
    assert pool.map(fails, [(0,), (1,)]) == [0, 1]   # the pool goes on
