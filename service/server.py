"""`lumenlink serve`: run the service under uvicorn (one worker: scenes live in this process's memory)."""

from __future__ import annotations

import contextlib
import logging
import os
import re
import sys
from pathlib import Path

LOOPBACK = ("127.0.0.1", "::1", "localhost")


def run(host: str = "127.0.0.1", port: int = 8000, data_dir: Path | str = "./var", warm: bool = True,
        token: str | None = None, dask: str | None = None, device: str = "auto") -> None:
    """Start uvicorn on `host`:`port` with the data (SQLite file, meshes, BLAS cache) under `data_dir`;
    `warm`: compile the light-transport kernels in the background from the start (`tracer.warmup`); `token`:
    the bearer token every request must carry (required beyond loopback); `dask`: the address of a Dask scheduler
    whose workers run the photon batches (`tracer.backends`); `device`: auto, cpu or cuda (`tracer.gpu.device`)."""
    from service.app import create_app
    from service.config import Settings
    from service.events import closing_server

    problem = data_dir_problem(Path(data_dir))
    if not token and host not in LOOPBACK:
        problem = (f"listening on {host} exposes the whole API (DELETE included) beyond this machine: set "
                   f"LUMENLINK_TOKEN (or --token) to a secret of at least 16 characters, or listen on 127.0.0.1")
    elif token and len(token) < 16:
        problem = "the token must have at least 16 characters"
    elif dask and not re.fullmatch(r"[a-z0-9+]+://\S+", dask):
        problem = f"--dask takes a scheduler address such as tcp://127.0.0.1:8786, got {dask!r}"
    elif device not in ("auto", "cpu", "cuda"):
        problem = f"--device takes auto, cpu or cuda, got {device!r}"
    elif device == "cuda":
        from tracer.gpu.device import DeviceUnavailable, choose

        try:
            choose(device)
        except DeviceUnavailable as exc:
            problem = str(exc)
    if problem:
        print(f"lumenlink serve: {problem}", file=sys.stderr)
        raise SystemExit(2)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    logging.getLogger("alembic").setLevel(logging.WARNING)  # migrations: only say something when it matters
    settings = Settings(host=host, port=port, data_dir=Path(data_dir), warm_kernels=warm, token=token or None,
                        dask_scheduler=dask or None, device=device)  # type: ignore[arg-type]  # checked above
    app = create_app(settings)
    # as uvicorn.run, with the pages' event streams ended when asked to stop (service.events.closing_server)
    server = closing_server(app, host=host, port=port, log_level="info", access_log=False, workers=1)
    try:
        with contextlib.suppress(KeyboardInterrupt):
            server.run()
    finally:   # the kernels' warm-up children end with the service (they would end on their own within a second)
        if app.state.kernels is not None:
            app.state.kernels.stop()
    if not server.started:
        raise SystemExit(3)   # uvicorn's STARTUP_FAILURE: the port was taken, say


def data_dir_problem(path: Path) -> str | None:
    """What keeps `path` from holding the service's data (created if absent), in words; None if nothing."""
    if path.exists() and not path.is_dir():
        return f"the data directory {str(path)!r} is a file: give a directory (it is created if absent)"
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        return f"cannot create the data directory {str(path)!r}: {exc.strerror}"
    if not os.access(path, os.W_OK | os.X_OK):
        return f"the data directory {str(path)!r} is not writable by this user: give a writable one"
    return None
