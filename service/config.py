"""The service's configuration: one pydantic-settings object, read from ``LUMENLINK_*`` variables.

The data directory holds the SQLite file (``lumenlink.sqlite3``), the uploaded meshes
(``meshes/``) and the BLAS cache (``blas/``). ``database_url`` may name any SQLAlchemy URL
(e.g. PostgreSQL); by default it is the SQLite file in the data directory.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field, model_validator
from pydantic_settings import BaseSettings, SettingsConfigDict


class Settings(BaseSettings):
    """Everything the service can be told; ``LUMENLINK_<NAME>`` sets ``<name>``."""

    model_config = SettingsConfigDict(env_prefix="LUMENLINK_", extra="forbid")

    data_dir: Path = Field(default=Path("./var"), description="SQLite file, meshes and BLAS cache.")
    database_url: str | None = Field(default=None, description="SQLAlchemy URL; default: SQLite in data_dir.")
    host: str = "127.0.0.1"
    port: int = Field(default=8000, ge=0, le=65535)
    max_body_bytes: int = Field(default=512 * 1024 * 1024, gt=0, description="Larger request bodies get 413.")
    max_upload_bytes_in_flight: int = Field(
        default=1024 * 1024 * 1024, gt=0, description="Request body bytes all requests together may be receiving at "
                                                      "once (at least max_body_bytes); a body beyond gets 503 and "
                                                      "Retry-After, so parallel uploads cannot exhaust memory.")
    max_points: int = Field(default=100_000, gt=0, description="Most query points one illuminance request may ask.")
    max_camera_pixels: int = Field(default=1920 * 1080, gt=0, description=(
        "Most pixels (width × height) a camera may have: one of more than max_points pixels is traced in bands of "
        "whole rows of at most max_points pixels each, assembled into one image; a larger camera is refused when "
        "it is made (422)."))
    max_photons: int = Field(default=1_000_000_000, gt=0, description="Most photons one query may trace.")
    max_seconds: float = Field(default=600.0, gt=0, description="Longest time budget one query may ask.")
    max_concurrent_queries: int = Field(default=2, gt=0, description="Synchronous queries running at once; more "
                                                                     "wait (see queue_wait_seconds), then 503.")
    queue_wait_seconds: float = Field(default=30.0, gt=0, description="How long a synchronous query waits for a "
                                                                      "free slot before it is answered 503, s.")
    max_nodes: int = Field(default=250_000, gt=0, description="Most nodes one pushed document may have (a whole "
                                                              "vehicle's product tree has ~1e5); more: 413, counted "
                                                              "from the bytes before any decoding.")
    log_requests: bool = Field(default=True, description="Log one line per request (method, path, status, ms).")
    token: str | None = Field(default=None, min_length=16, description=(
        "Bearer token every request but /health, /docs, /redoc and /openapi.json must carry "
        "(`Authorization: Bearer …`); required when the service listens beyond loopback."))
    dask_scheduler: str | None = Field(default=None, pattern=r"^[a-z0-9+]+://\S+$", description=(
        "Address of a Dask scheduler (`tcp://host:8786`): the photon batches of every query, sensor simulation "
        "and job then run as tasks on its workers (`tracer.backends`), with the same answers; unset: in this "
        "process."))
    dask_timeout: float = Field(default=10.0, gt=0, le=600, description=(
        "Seconds to wait for the Dask scheduler (to connect, or for a stalled round to move) before a query "
        "is answered 503."))
    keep_results: int = Field(default=20, ge=1, le=1000, description=(
        "Results kept per sensor (`service.results`: one per scene revision and assignment state, the oldest "
        "dropped first), for `GET /scenes/{id}/sensors/{sid}/results`, their maps and differences."))
    removed_keep_revisions: int = Field(default=100, ge=0, le=1_000_000, description=(
        "How many revisions the scene remembers a removed node (path, product, shape signature, placement, the "
        "assignments it carried: `GET /scenes/{id}/removed-nodes`), so that a node that comes back gets its UUID "
        "again; 0: none."))
    removed_keep_days: float = Field(default=30.0, ge=0, le=36500, description=(
        "How many days the scene remembers a removed node (whichever of this and removed_keep_revisions ends "
        "first)."))
    warm_kernels: bool = Field(default=False, description="Compile the query kernels in a child process from the "
                                                          "start (`tracer.warmup`; `lumenlink serve` turns it on).")
    device: Literal["auto", "cpu", "cuda"] = Field(default="auto", description=(
        "Where to compute (`tracer.gpu.device`): auto takes CUDA where numba-cuda finds a GPU, else the CPU (the "
        "reason logged once); cuda without a GPU stops `lumenlink serve` at start. On CUDA the photon batches run "
        "on the card (without a Dask cluster); a scene that does not fit there is answered on the CPU, saying why; "
        "every answer's `device` says where they ran."))

    @model_validator(mode="after")
    def _uploads_fit(self) -> Settings:
        if self.max_upload_bytes_in_flight < self.max_body_bytes:
            raise ValueError(f"max_upload_bytes_in_flight ({self.max_upload_bytes_in_flight}) must be at least "
                             f"max_body_bytes ({self.max_body_bytes}): one largest body must fit")
        return self

    def resolved_database_url(self) -> str:
        """The SQLAlchemy URL in use."""
        if self.database_url:
            return self.database_url
        return f"sqlite:///{(self.data_dir / 'lumenlink.sqlite3').resolve()}"

    @property
    def mesh_dir(self) -> Path:
        return self.data_dir / "meshes"

    @property
    def blas_dir(self) -> Path:
        return self.data_dir / "blas"
