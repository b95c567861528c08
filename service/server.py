"""`lumenlink serve`: run the service under uvicorn (one worker: scenes live in this process's memory)."""

from __future__ import annotations

import logging
from pathlib import Path


def run(host: str = "127.0.0.1", port: int = 8000, data_dir: Path | str = "./var", warm: bool = True) -> None:
    """Start uvicorn on `host`:`port` with the data (SQLite file, meshes, BLAS cache) under `data_dir`;
    `warm`: compile the light-transport kernels in the background from the start (`tracer.warmup`)."""
    import uvicorn

    from service.app import create_app
    from service.config import Settings

    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    logging.getLogger("alembic").setLevel(logging.WARNING)  # migrations: only say something when it matters
    settings = Settings(host=host, port=port, data_dir=Path(data_dir), warm_kernels=warm)
    app = create_app(settings)
    uvicorn.run(app, host=host, port=port, log_level="info", access_log=False, workers=1)
