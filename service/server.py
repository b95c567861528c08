"""`lumenlink serve`: run the service under uvicorn (one worker: scenes live in this process's memory)."""

from __future__ import annotations

import logging
import os
import sys
from pathlib import Path


def run(host: str = "127.0.0.1", port: int = 8000, data_dir: Path | str = "./var", warm: bool = True) -> None:
    """Start uvicorn on `host`:`port` with the data (SQLite file, meshes, BLAS cache) under `data_dir`;
    `warm`: compile the light-transport kernels in the background from the start (`tracer.warmup`)."""
    import uvicorn

    from service.app import create_app
    from service.config import Settings

    problem = data_dir_problem(Path(data_dir))
    if problem:
        print(f"lumenlink serve: {problem}", file=sys.stderr)
        raise SystemExit(2)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    logging.getLogger("alembic").setLevel(logging.WARNING)  # migrations: only say something when it matters
    settings = Settings(host=host, port=port, data_dir=Path(data_dir), warm_kernels=warm)
    app = create_app(settings)
    uvicorn.run(app, host=host, port=port, log_level="info", access_log=False, workers=1)


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
