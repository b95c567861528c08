"""The FastAPI application: `create_app(settings)` wires storage, the scene manager and the routers.

`app.state.settings` holds the `Settings`, `app.state.manager` the `SceneManager`, and
`app.state.live` the `LiveRegistry` the simulation routes read (docs/CONTRACTS.md).
"""

from __future__ import annotations

import importlib.util
import logging
from collections.abc import Callable
from typing import Any

from fastapi import FastAPI

import service
from service.config import Settings
from service.db import open_engine
from service.errors import install_handlers
from service.meshes import MeshStore
from service.middleware import BearerToken, BodyLimit, RequestLog
from service.routes import assignments, geometries, scenes
from service.state import SceneManager

log = logging.getLogger("lumenlink.service")


def create_app(settings: Settings | None = None, scene_factory: Callable[[], Any] | None = None) -> FastAPI:
    """Build the app for `settings` (default: from ``LUMENLINK_*``); runs the database migrations.

    `scene_factory` makes the per-scene `tracer.Scene`; tests may pass a stand-in.
    """
    settings = settings or Settings()
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    engine = open_engine(settings.resolved_database_url())
    manager = SceneManager(settings, engine, MeshStore(settings.mesh_dir), scene_factory=scene_factory)

    app = FastAPI(title="LumenLink sync service", version=getattr(service, "__version__", "0.1.0"),
                  description="Keeps a light simulation in step with a CAD model: push CAD trees, "
                              "assign materials, lights and sensors by UUID, query illuminance.")
    app.state.settings = settings
    app.state.manager = manager
    app.state.live = manager.live
    app.state.engine = engine
    install_handlers(app)

    app.state.kernels = None
    if settings.warm_kernels:  # compile the query kernels in a child process, on the other core (tracer.warmup)
        from tracer.warmup import start_background

        app.state.kernels = start_background()

    @app.get("/health", tags=["service"])
    def health() -> dict[str, Any]:
        """Liveness: the process answers and its database is reachable; `kernels` says whether the
        light-transport kernels are compiled yet (`warming`, `ready` with seconds per stage, or `failed`)."""
        from sqlalchemy import text

        with engine.connect() as conn:
            conn.execute(text("SELECT 1"))
        kernels = app.state.kernels.status() if app.state.kernels is not None else {"state": "not warmed"}
        return {"status": "ok", "kernels": kernels}

    app.include_router(scenes.router)
    app.include_router(geometries.router)
    app.include_router(assignments.router)
    if importlib.util.find_spec("service.routes.simulation") is not None:
        from service.routes import simulation

        app.include_router(simulation.router)
    app.add_middleware(BodyLimit, max_bytes=settings.max_body_bytes)
    if settings.token:
        app.add_middleware(BearerToken, token=settings.token)
    if settings.log_requests:
        app.add_middleware(RequestLog)
    return app
