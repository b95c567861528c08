"""A real `lumenlink serve` process for tests: uvicorn on a free loopback port, SQLite under a temp dir.

    with running_service(tmp_path) as base_url:
        httpx.get(f"{base_url}/health")

The process's output goes to ``<data_dir>/<log_name>`` (``service.log`` unless told; shown in the error if it fails to
start). On exit it gets SIGTERM (uvicorn shuts down cleanly) and, if it lingers, SIGKILL.
"""

from __future__ import annotations

import contextlib
import os
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import httpx

ROOT = Path(__file__).resolve().parents[1]


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextlib.contextmanager
def running_service(data_dir: Path | str, env: dict[str, str] | None = None,
                    startup_timeout: float = 120.0, log_name: str = "service.log") -> Iterator[str]:
    """Start ``lumenlink serve --data-dir data_dir`` and yield its base URL once /health answers 200.

    Parameters
    ----------
    data_dir : the service's data directory (SQLite file, meshes, BLAS cache); created if missing.
    env : extra environment variables, e.g. ``{"LUMENLINK_MAX_BODY_BYTES": "1000"}``.
    startup_timeout : seconds to wait for /health.
    log_name : the log file's name in `data_dir` (processes sharing one data dir keep their own).
    """
    data_dir = Path(data_dir)
    data_dir.mkdir(parents=True, exist_ok=True)
    port = free_port()
    base_url = f"http://127.0.0.1:{port}"
    # no kernel-compiling child per test server (tracer.warmup): the test process compiles them once;
    # a test that wants one says so in `env`
    full_env = {**os.environ, "LUMENLINK_WARM_KERNELS": "false", **(env or {})}
    full_env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), full_env.get("PYTHONPATH")]))
    log_path = data_dir / log_name
    with open(log_path, "ab") as log:
        proc = subprocess.Popen(
            [sys.executable, "-m", "lumenlink.cli", "serve", "--host", "127.0.0.1", "--port", str(port),
             "--data-dir", str(data_dir)],
            cwd=ROOT, env=full_env, stdout=log, stderr=subprocess.STDOUT,
        )
    try:
        deadline = time.monotonic() + startup_timeout
        while True:
            if proc.poll() is not None:
                raise RuntimeError(f"lumenlink serve exited with {proc.returncode}:\n{log_path.read_text()[-4000:]}")
            try:
                if httpx.get(f"{base_url}/health", timeout=2.0).status_code == 200:
                    break
            except httpx.HTTPError:
                pass
            if time.monotonic() > deadline:
                raise RuntimeError(f"lumenlink serve did not answer /health within {startup_timeout} s:\n"
                                   f"{log_path.read_text()[-4000:]}")
            time.sleep(0.1)
        yield base_url
    finally:
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout=5)
