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
#: the PTX child the controller started, where the session runs tests/tracer/gpu/test_gpu_ptx.py
PTX_CHILD = pytest.StashKey()


def pytest_configure(config):
    """With pytest-xdist's workers (``make test``: ``-n 2``), the controller starts the service's warm-up children
    (`tracer.warmup.start_background`) before the workers start: they compile the query kernels into the session's
    numba cache in parallel, one per core, while the first test files run, and a worker whose test needs a kernel
    meanwhile waits on its compile lock (`tracer.compile_locks`) and loads it, instead of compiling it as well. What
    they compiled is reported to tests/tracer/test_warmup.py (`tests.warmup_report`). It also starts the child that
    compiles numba-cuda's kernels to PTX (`tests.ptx_child`), at the lowest priority, for
    tests/tracer/gpu/test_gpu_ptx.py to read at the end."""
    if getattr(config.option, "numprocesses", None) and not hasattr(config, "workerinput"):
        from tests import ptx_child
        from tests.warmup_report import cache_is_empty, report_when_done
        from tracer.warmup import start_background

        cold = cache_is_empty()
        config.stash[WARM_UP] = start_background()
        report_when_done(config.stash[WARM_UP], cold)
        if ptx_child.wanted(list(config.args), Path(str(config.invocation_params.dir))):
            config.stash[PTX_CHILD] = ptx_child.start_background()


def pytest_unconfigure(config):
    background = config.stash.get(WARM_UP, None)
    if background is not None:
        background.stop()
    if config.stash.get(PTX_CHILD, None) is not None:
        from tests import ptx_child

        ptx_child.stop(config.stash[PTX_CHILD])


#: wall seconds of the files that take longest under ``make test`` (2026-11-29, empty numba cache): they start first,
#: so that no long file is left to one worker at the end while the other idles (longest first; pytest-xdist's own
#: order, by number of tests, ran the PTX check's three tests last, 169 s). A file not listed keeps its place after
#: them; tests/tracer/test_warmup.py and the GPU simulator's transport are left out: they mostly wait for the
#: warm-up children or a child process.
LONGEST_FIRST = {
    "tests/cad_adapter/test_cad_cli_service.py": 113, "tests/service/test_fuzz.py": 109, "tests/e2e/test_pages.py": 58,
    "tests/service/test_hardening.py": 48, "tests/tracer/optics/test_surfaces_contract.py": 45,
    "tests/tracer/transport/test_tessellation_error.py": 38, "tests/service/test_dask_service.py": 33,
    "tests/tracer/test_dask_backend.py": 29, "tests/tracer/test_errors.py": 29, "tests/service/test_bad_input.py": 28,
    "tests/service/test_service_process.py": 27, "tests/tracer/transport/test_cost.py": 26,
    "tests/tracer/transport/test_spectral_transport.py": 23, "tests/tracer/transport/test_physics_left_out.py": 22,
    "tests/service/test_tree_diff.py": 22, "tests/e2e/test_engineer_loop.py": 21, "tests/service/test_pages_api.py": 21,
    "tests/service/test_replicas.py": 21, "tests/service/test_cuda_service.py": 20,
    "tests/cad_adapter/test_freecad.py": 100, "tests/cad_adapter/test_freecad_gui.py": 30,
}
#: files that run last, in this order: the benchmarks' smoke tests, whose child processes then load the tracer's
#: kernels from numba's cache, which the tests before them filled, instead of compiling them all again on a cold
#: machine (about 200 s of CI time on 2 cores); then the PTX check, which reads what the controller's child compiled
#: meanwhile (`tests.ptx_child`)
LAST = ("tests/bench/", "tests/tracer/gpu/test_gpu_ptx.py")


def pytest_collection_modifyitems(session, config, items):
    """Files in the order `LONGEST_FIRST`, the rest, `LAST` (``make test`` runs pytest-xdist with
    ``--no-loadscope-reorder``, so that its workers take them in this order)."""
    def place(item: pytest.Item) -> tuple[int, float]:
        name = Path(str(item.path)).relative_to(ROOT).as_posix()
        last = [i for i, prefix in enumerate(LAST) if name.startswith(prefix)]
        if last:
            return 1 + last[0], 0.0
        return 0, -LONGEST_FIRST.get(name, 0.0)

    items.sort(key=place)
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
