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
from pydantic import BaseModel, Field

import service
from service.config import Settings
from service.db import open_engine
from service.errors import install_handlers
from service.meshes import MeshStore
from service.middleware import BearerToken, BodyLimit, RequestLog
from service.optical_files import OpticalFiles
from service.routes import assignments, elements, geometries, optical_files, pages, scenes
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
                  docs_url=None, redoc_url=None,   # served by service.routes.pages, with their assets local
                  description="Keeps a light simulation in step with a CAD model: push CAD trees, "
                              "assign materials, lights and sensors by UUID, query illuminance.")
    app.state.settings = settings
    app.state.manager = manager
    app.state.live = manager.live
    app.state.engine = engine
    install_handlers(app)

    app.state.kernels = None
    # compile the query kernels in a child process, on the other core (tracer.warmup); with a Dask cluster the
    # workers compile their own, and this process runs no batch
    if settings.warm_kernels and not settings.dask_scheduler:
        from tracer.warmup import start_background

        app.state.kernels = start_background()

    @app.get("/health", tags=["service"], responses=PROBLEM_RESPONSES)
    def health() -> dict[str, Any]:
        """Liveness: the process answers and its database is reachable; `kernels` says whether the
        light-transport kernels are compiled yet (`warming`, `ready` with seconds per stage, or `failed`)."""
        from sqlalchemy import text

        with engine.connect() as conn:
            conn.execute(text("SELECT 1"))
        kernels = app.state.kernels.status() if app.state.kernels is not None else {"state": "not warmed"}
        return {"status": "ok", "kernels": kernels}

    app.include_router(scenes.router, responses=PROBLEM_RESPONSES)
    app.include_router(geometries.router, responses=PROBLEM_RESPONSES)
    app.include_router(assignments.router, responses=PROBLEM_RESPONSES)
    app.include_router(elements.router, responses=PROBLEM_RESPONSES)
    app.state.optical_files = OpticalFiles(settings.data_dir / "optical-files")   # registered with the tracer
    app.include_router(optical_files.router, responses=PROBLEM_RESPONSES)
    if importlib.util.find_spec("service.routes.simulation") is not None:
        from service.routes import simulation

        app.include_router(simulation.router, responses=PROBLEM_RESPONSES)
        from service.routes import results

        app.include_router(results.router, responses=PROBLEM_RESPONSES)
        from service.routes import images

        app.include_router(images.router, responses=PROBLEM_RESPONSES)
        from service.routes import glare

        app.include_router(glare.router, responses=PROBLEM_RESPONSES)
    # the pages for people, the API docs with their assets, the event streams; before the middleware below
    pages.install(app, responses=PROBLEM_RESPONSES)
    app.openapi = _openapi_with_problems(app)  # type: ignore[method-assign]  # FastAPI documents this override
    app.add_middleware(BodyLimit, max_bytes=settings.max_body_bytes, in_flight=settings.max_upload_bytes_in_flight)
    if settings.token:
        app.add_middleware(BearerToken, token=settings.token)
    if settings.log_requests:
        app.add_middleware(RequestLog)
    return app


class Problem(BaseModel):
    """An error (RFC 9457 problem details), as every error of this service is answered."""

    type: str = Field("about:blank", description="A URI naming the kind of problem; `about:blank`: the status says.")
    title: str = Field(description="The status's reason phrase (e.g. `Unprocessable Content`).")
    status: int = Field(description="The HTTP status code.")
    detail: str = Field(description="What went wrong with this request, for people.")
    errors: list[dict[str, Any]] | None = Field(None, description="422: each invalid field (loc, msg, type).")
    limit: int | None = Field(None, description="413: the limit exceeded.")
    current_revision: int | None = Field(None, description="409: the scene's revision now.")
    incident: str | None = Field(None, description="500: the id the service log has the details under.")


PROBLEM_RESPONSES: dict[int | str, dict[str, Any]] = {
    code: {"model": Problem, "description": why} for code, why in (
        (400, "Malformed request (a body that is not JSON)."), (401, "Missing or wrong bearer token."),
        (404, "No such scene, node, geometry, sensor or job."), (409, "A stale base_revision, or a conflict."),
        (413, "Too large (a body, or a query beyond the service's limits)."),
        (422, "Invalid input: the detail names each field."), (500, "An unexpected error (incident id)."),
        (503, "Busy (all query slots taken, or the job queue full): retry later."))}


PROBLEM_REF = {"$ref": "#/components/schemas/Problem"}


def _openapi_with_problems(app: FastAPI) -> Any:
    """The app's OpenAPI document with its errors as they are sent (``application/problem+json``) and the
    models the hand-decoded document body refers to (`service.routes.scenes.DOCUMENT_SCHEMA_DEFS`)."""
    base = app.openapi

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is not None:
            return app.openapi_schema
        schema = base()
        components = schema.setdefault("components", {}).setdefault("schemas", {})
        for name, model in scenes.DOCUMENT_SCHEMA_DEFS.items():
            components.setdefault(name, model)
        for path in schema.get("paths", {}).values():
            for operation in path.values():
                for code, response in operation.get("responses", {}).items():
                    if code[:1] in "45":   # every error is a problem, whatever a route declared
                        response["content"] = {"application/problem+json": {"schema": PROBLEM_REF}}
        for name in ("HTTPValidationError", "ValidationError"):
            components.pop(name, None)   # FastAPI's own error models: never sent by this service
        for path in schema.get("paths", {}).values():
            for operation in path.values():
                for media in operation.get("requestBody", {}).get("content", {}).values():
                    if "examples" not in media and (examples := _body_examples(media.get("schema", {}), components)):
                        media["examples"] = examples
        return schema

    return openapi


def _body_examples(schema: dict[str, Any], components: dict[str, Any]) -> dict[str, Any]:
    """A request body's examples as /docs offers them (a named list to pick from): those of its model, or of each
    model a union body may be (a light: point, spot, …), from the models' ``json_schema_extra``."""
    out: dict[str, Any] = {}
    for branch in schema.get("oneOf") or schema.get("anyOf") or [schema]:
        name = branch.get("$ref", "").rsplit("/", 1)[-1]
        model = components.get(name, branch) if name else branch
        for k, value in enumerate(model.get("examples") or []):
            title = name or model.get("title") or "example"
            out[title if k == 0 else f"{title} {k + 1}"] = {"summary": title if k == 0 else f"{title} ({k + 1})",
                                                           "value": value}
    return out

