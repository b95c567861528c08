"""Shared test fixtures: paths to the shared fixtures and a seeded random generator."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

# A token in the developer's environment would make every service under test ask for it: the tests that want
# one set it themselves.
os.environ.pop("LUMENLINK_TOKEN", None)

ROOT = Path(__file__).resolve().parents[1]
SHARED_FIXTURES = ROOT.parent / "shared" / "fixtures"


#: the warm-up children the controller started (`pytest_configure`)
WARM_UP = pytest.StashKey()


def pytest_configure(config):
    """With pytest-xdist's workers (``make test``: ``-n 2``), the controller starts the service's warm-up children
    (`tracer.warmup.start_background`) before the workers start: they compile the query kernels into the session's
    numba cache in parallel, one per core, while the first test files run, and a worker whose test needs a kernel
    meanwhile waits on its compile lock (`tracer.compile_locks`) and loads it, instead of compiling it as well. What
    they compiled is reported to tests/tracer/test_warmup.py (`tests.warmup_report`)."""
    if getattr(config.option, "numprocesses", None) and not hasattr(config, "workerinput"):
        from tests.warmup_report import cache_is_empty, report_when_done
        from tracer.warmup import start_background

        cold = cache_is_empty()
        config.stash[WARM_UP] = start_background()
        report_when_done(config.stash[WARM_UP], cold)


def pytest_unconfigure(config):
    background = config.stash.get(WARM_UP, None)
    if background is not None:
        background.stop()


def pytest_collection_modifyitems(session, config, items):
    """The benchmarks' smoke tests (tests/bench) last: their child processes then load the tracer's kernels from
    numba's cache, which the tests before them filled, instead of compiling them all again on a cold machine
    (about 200 s of CI time on 2 cores)."""
    items.sort(key=lambda item: Path(str(item.path)).is_relative_to(ROOT / "tests" / "bench"))
    for item in items:
        give_its_own_id(item)


def give_its_own_id(item: pytest.Item) -> None:
    """Schemathesis 4.32 under pytest 9 gives every operation's case of a test one node id, the test's
    (``test_fuzz.py::test_x``, its name ``test_x[GET /health]``): pytest-xdist, which hands out tests by node id,
    then runs one of tests/service/test_fuzz.py's 61 operations and drops the rest. Each case gets its name back
    in its id."""
    if (type(item).__name__ == "SchemathesisFunction" and "[" not in item.nodeid and hasattr(item, "_id")
            and hasattr(item.parent, "id")):
        item._id = item.parent.id.child(item.name)   # pytest 9 keeps a node's id as a NodeId in `_id`


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20081946)
