"""What the test session's warm-up children compiled, for tests/tracer/test_warmup.py.

Under ``make test`` the controller starts the service's warm-up children (tests/conftest.py); the test that checks
what they compile from an empty cache runs in a worker, another process. The controller writes their report, once
every stage has ended, to the JSON file named by `WARM_UP_REPORT` in the environment the workers inherit."""

from __future__ import annotations

import json
import os
import tempfile
import threading
from pathlib import Path

#: the environment variable naming the report's file
WARM_UP_REPORT = "LUMENLINK_TEST_WARMUP_REPORT"


def cache_is_empty() -> bool:
    """True when numba's cache directory (`tracer.numba_cache_dir`, or NUMBA_CACHE_DIR) holds no index file."""
    import numba

    import tracer  # noqa: F401  (it chooses the directory)

    folder = os.environ.get("NUMBA_CACHE_DIR") or numba.config.CACHE_DIR
    return not folder or not any(Path(folder).rglob("*.nbi"))


def report_when_done(background, cold: bool) -> Path:
    """Name the report's file in the environment and write it once `background` (`tracer.warmup.Background`) has
    ended: {"cold": whether the cache was empty before it started, "status", "compiled": {stage: [kernel]}}."""
    path = Path(tempfile.mkdtemp(prefix="lumenlink-warmup-")) / "report.json"
    os.environ[WARM_UP_REPORT] = str(path)

    def write() -> None:
        for stage in background.stages:
            background.wait(stage, timeout=1800)
        background.join(timeout=60)
        partial = path.with_suffix(".partial")
        partial.write_text(json.dumps({"cold": cold, "status": background.status(), "compiled": background.compiled}))
        partial.replace(path)

    threading.Thread(target=write, name="lumenlink-warmup-report", daemon=True).start()
    return path
