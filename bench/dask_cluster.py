"""A real Dask cluster on this machine, for tests and benchmarks: a ``dask scheduler`` process and ``dask worker``
processes on loopback.

    with dask_cluster(workers=2) as cluster:
        DaskBackend(cluster.address)
        cluster.workers[0].kill()

Each process logs to ``<log_dir>/<name>.log`` (shown if it fails to start). The workers run in this
interpreter's environment with the repository on their path, one thread each, and share this process's
numba cache, so kernels compiled here load there in seconds. On exit every process is killed.
"""

from __future__ import annotations

import contextlib
import os
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DASK = str(Path(sys.executable).with_name("dask"))


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@dataclass
class Cluster:
    address: str
    scheduler: subprocess.Popen
    workers: list[subprocess.Popen] = field(default_factory=list)
    log_dir: Path = Path(".")

    def logs(self) -> str:
        return "\n".join(f"--- {p.name}\n{p.read_text()[-3000:]}" for p in sorted(self.log_dir.glob("*.log")))


def _env() -> dict[str, str]:
    env = {**os.environ, "DASK_DISTRIBUTED__WORKER__DAEMON": "False"}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    return env


def _start(args: list[str], log_dir: Path, name: str) -> subprocess.Popen:
    with open(log_dir / f"{name}.log", "ab") as log:
        return subprocess.Popen([DASK, *args], cwd=ROOT, env=_env(), stdout=log, stderr=subprocess.STDOUT)


def _wait_for_workers(address: str, n: int, cluster: Cluster, timeout: float) -> None:
    from distributed import Client

    deadline = time.monotonic() + timeout
    with Client(address, timeout=timeout, set_as_default=False) as client:
        while len(client.scheduler_info(n_workers=-1)["workers"]) < n:
            if time.monotonic() > deadline:
                raise RuntimeError(f"{n} Dask workers did not join within {timeout} s:\n{cluster.logs()}")
            time.sleep(0.1)


@contextlib.contextmanager
def dask_cluster(log_dir: Path, workers: int = 2, startup_timeout: float = 90.0) -> Iterator[Cluster]:
    """Start a scheduler on a free loopback port and `workers` one-thread workers; yield once all joined."""
    log_dir.mkdir(parents=True, exist_ok=True)
    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    scheduler = _start(["scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"], log_dir,
                       "scheduler")
    cluster = Cluster(address, scheduler, log_dir=log_dir)
    try:
        for k in range(workers):
            cluster.workers.append(_start(["worker", address, "--nthreads", "1", "--nworkers", "1",
                                           "--no-dashboard", "--name", f"w{k}"], log_dir, f"worker{k}"))
        _wait_for_workers(address, workers, cluster, startup_timeout)
        yield cluster
    finally:
        for p in [*cluster.workers, scheduler]:
            if p.poll() is None:
                p.kill()
        for p in [*cluster.workers, scheduler]:
            with contextlib.suppress(subprocess.TimeoutExpired):
                p.wait(timeout=10)
