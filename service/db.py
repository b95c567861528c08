"""Storage schema and engine: SQLAlchemy 2 tables, SQLite in WAL mode by default, Alembic migrations.

Tables (one row per thing, keyed by scene):

- ``scenes``: id, name (unique), current revision, the document's length unit and source, and
  ``assign_revision``: a counter bumped by every change that keeps the revision (an assignment, an
  identity-only push), so that several service processes on one database can tell, with one SELECT of
  ``(revision, assign_revision)``, whether what they hold in memory is behind (`service.scenes.Scenes.state`).
- ``revisions``: one row per accepted push that changed something (the diff summary, seconds).
- ``nodes``: the current tree, one row per node uuid; a push writes only the rows that changed.
  Transforms are 16 little-endian float64 (exact round trip).
- ``node_identity``: per scene and node uuid, what the CAD adapter matches a node by besides the
  tree (product name, shape signature as JSON); a push writes only the records that changed and
  deletes those of nodes that lost theirs. Keyed by value like the nodes (no foreign key to them).
- ``removed_nodes``: per scene, the nodes pushes removed (their last node and identity records, path, world
  placement and the assignments they carried), kept for ``removed_keep_revisions`` revisions and
  ``removed_keep_days`` days, so that a node that comes back gets its UUID again (`service.push`).
- ``geometries``: uploaded meshes (the arrays live in content-addressed files under the data dir).
- ``materials``, ``lights``, ``sensors``, ``sim_objects``: assignments by uuid; they refer to a
  node uuid by value (no foreign key), so they outlive the node and are orphaned, not deleted.
- ``sensor_results``: the last results of each sensor (``service.results``), one per scene revision and
  state (``edit``: 0, 1, … for successive assignment states at one revision), lux and standard error as
  little-endian float64 bytes; they outlive the sensor, not the scene.
- ``far_field_results``: the latest result of each far-field sensor (cd on its C-γ grid, as the answer gives it),
  what its IES / EULUMDAT export reads (``service.results.ResultStore.keep_far``); it outlives a restart.
- ``elements``: the library of prepared optical elements with an inside, shared by every scene (the body, its
  summary; the prepared arrays live in a file per element under the data dir, `service.elements`).
- ``element_assignments``: an element put onto a node's support faces (by node uuid, orphaned like the others).

`open_engine` creates the engine and brings the schema to the latest migration
(``alembic upgrade head``, run programmatically from the packaged ``service/migrations``).
"""

from __future__ import annotations

from pathlib import Path

from sqlalchemy import (
    JSON,
    BigInteger,
    Boolean,
    Column,
    DateTime,
    Engine,
    Float,
    ForeignKey,
    Integer,
    LargeBinary,
    MetaData,
    String,
    Table,
    create_engine,
    event,
    func,
    text,
)

metadata = MetaData()

scenes = Table(
    "scenes", metadata,
    Column("id", String(36), primary_key=True),
    Column("name", String(200), nullable=False, unique=True),
    Column("revision", Integer, nullable=False, default=0),
    Column("assign_revision", Integer, nullable=False, server_default="0"),
    Column("length_unit", String(8), nullable=True),
    Column("source", JSON, nullable=True),
    Column("created_at", DateTime(timezone=True), nullable=False, server_default=func.now()),
    Column("updated_at", DateTime(timezone=True), nullable=False, server_default=func.now()),
)

revisions = Table(
    "revisions", metadata,
    Column("scene_id", String(36), ForeignKey("scenes.id", ondelete="CASCADE"), primary_key=True),
    Column("revision", Integer, primary_key=True),
    Column("created_at", DateTime(timezone=True), nullable=False, server_default=func.now()),
    Column("summary", JSON, nullable=False),
)

nodes = Table(
    "nodes", metadata,
    Column("scene_id", String(36), ForeignKey("scenes.id", ondelete="CASCADE"), primary_key=True),
    Column("uuid", String(36), primary_key=True),
    Column("position", Float, nullable=False),  # document order (a float: appends never renumber)
    Column("parent", String(36), nullable=True),
    Column("name", String(500), nullable=False),
    Column("transform", LargeBinary(128), nullable=False),
    Column("geometry", String(64), nullable=True),
    Column("color", JSON, nullable=True),
)

node_identity = Table(
    "node_identity", metadata,
    Column("scene_id", String(36), ForeignKey("scenes.id", ondelete="CASCADE"), primary_key=True),
    Column("uuid", String(36), primary_key=True),
    Column("product", String(500), nullable=True),
    Column("signature", JSON, nullable=True),  # service.schemas.Signature as a dict, or null
)

removed_nodes = Table(
    "removed_nodes", metadata,
    Column("scene_id", String(36), ForeignKey("scenes.id", ondelete="CASCADE"), primary_key=True),
    Column("uuid", String(36), primary_key=True),
    Column("revision", Integer, nullable=False),  # the revision that removed it
    Column("removed_at", DateTime(timezone=True), nullable=False),
    Column("record", JSON, nullable=False),  # what GET /scenes/{id}/removed-nodes answers for it
)

geometries = Table(
    "geometries", metadata,
    Column("id", String(64), primary_key=True),
    Column("n_vertices", Integer, nullable=False),
    Column("n_triangles", Integer, nullable=False),
    Column("has_normals", Boolean, nullable=False),
    Column("size_bytes", Integer, nullable=False),
    Column("created_at", DateTime(timezone=True), nullable=False, server_default=func.now()),
)

materials = Table(
    "materials", metadata,
    Column("scene_id", String(36), ForeignKey("scenes.id", ondelete="CASCADE"), primary_key=True),
    Column("node", String(36), primary_key=True),  # node uuid or sim-object id
    Column("body", JSON, nullable=False),
)

lights = Table(
    "lights", metadata,
    Column("id", String(36), primary_key=True),
    Column("scene_id", String(36), ForeignKey("scenes.id", ondelete="CASCADE"), nullable=False, index=True),
    Column("body", JSON, nullable=False),
    Column("created_at", DateTime(timezone=True), nullable=False, server_default=func.now()),
)

sensors = Table(
    "sensors", metadata,
    Column("id", String(36), primary_key=True),
    Column("scene_id", String(36), ForeignKey("scenes.id", ondelete="CASCADE"), nullable=False, index=True),
    Column("body", JSON, nullable=False),
    Column("created_at", DateTime(timezone=True), nullable=False, server_default=func.now()),
)

sim_objects = Table(
    "sim_objects", metadata,
    Column("id", String(36), primary_key=True),
    Column("scene_id", String(36), ForeignKey("scenes.id", ondelete="CASCADE"), nullable=False, index=True),
    Column("body", JSON, nullable=False),
    Column("created_at", DateTime(timezone=True), nullable=False, server_default=func.now()),
)

sensor_results = Table(
    "sensor_results", metadata,
    Column("scene_id", String(36), ForeignKey("scenes.id", ondelete="CASCADE"), primary_key=True),
    Column("sensor_id", String(36), primary_key=True),
    Column("revision", Integer, primary_key=True),
    Column("edit", Integer, primary_key=True),
    Column("state", String(64), nullable=False),     # digest of what the result depends on besides geometry
    Column("created_at", DateTime(timezone=True), nullable=False),
    Column("photons", BigInteger, nullable=False),
    Column("seconds", Float, nullable=False),
    Column("min_lux", Float, nullable=False),
    Column("mean_lux", Float, nullable=False),
    Column("max_lux", Float, nullable=False),
    Column("meta", JSON, nullable=False),            # type, shape, frame, estimator, stop reason, effects
    Column("lux", LargeBinary, nullable=False),
    Column("stderr", LargeBinary, nullable=False),
)

far_field_results = Table(
    "far_field_results", metadata,
    Column("scene_id", String(36), ForeignKey("scenes.id", ondelete="CASCADE"), primary_key=True),
    Column("sensor_id", String(36), primary_key=True),
    Column("created_at", DateTime(timezone=True), nullable=False),
    Column("payload", JSON, nullable=False),        # the far-field answer: candela, stderr, grid, flux, revision
)

elements = Table(
    "elements", metadata,
    Column("id", String(64), primary_key=True),     # SHA-256 of the checked body: the same body, the same id
    Column("body", JSON, nullable=False),
    Column("features", BigInteger, nullable=True),  # null: a periodic layout, as many as its support holds
    Column("bytes", BigInteger, nullable=False),
    Column("prepare_seconds", Float, nullable=False),
    Column("created_at", DateTime(timezone=True), nullable=False, server_default=func.now()),
)

element_assignments = Table(
    "element_assignments", metadata,
    Column("id", String(36), primary_key=True),
    Column("scene_id", String(36), ForeignKey("scenes.id", ondelete="CASCADE"), nullable=False, index=True),
    Column("body", JSON, nullable=False),           # {"element", "node", "facing" | "faces"}
    Column("created_at", DateTime(timezone=True), nullable=False, server_default=func.now()),
)

MIGRATIONS = Path(__file__).resolve().parent / "migrations"
MIGRATION_LOCK = 0x4C756D656E   # PostgreSQL advisory lock key held while migrating ("Lumen")


def _sqlite_pragmas(dbapi_connection, _record) -> None:  # pragma: no cover - trivial
    cur = dbapi_connection.cursor()
    cur.execute("PRAGMA journal_mode=WAL")
    cur.execute("PRAGMA synchronous=NORMAL")
    cur.execute("PRAGMA foreign_keys=ON")
    cur.execute("PRAGMA busy_timeout=10000")
    cur.close()


def engine_url(url: str) -> str:
    """`url` with PostgreSQL's plain schemes (``postgresql://``, ``postgres://``) naming the driver this
    project installs (psycopg 3: ``postgresql+psycopg://``); SQLAlchemy would otherwise look for psycopg2."""
    for plain in ("postgresql://", "postgres://"):
        if url.startswith(plain):
            return "postgresql+psycopg://" + url[len(plain):]
    return url


def open_engine(url: str, migrate: bool = True) -> Engine:
    """An engine for `url` (SQLite gets WAL, foreign keys, a busy timeout), migrated to the latest schema."""
    url = engine_url(url)
    is_sqlite = url.startswith("sqlite")
    engine = create_engine(url, connect_args={"check_same_thread": False} if is_sqlite else {},
                           pool_pre_ping=not is_sqlite)
    if is_sqlite:
        event.listen(engine, "connect", _sqlite_pragmas)
    if migrate:
        upgrade(engine)
    return engine


def upgrade(engine: Engine) -> None:
    """``alembic upgrade head`` on `engine`, using the migrations packaged with the service."""
    from alembic import command
    from alembic.config import Config

    cfg = Config(str(MIGRATIONS / "alembic.ini"))
    cfg.set_main_option("script_location", str(MIGRATIONS))
    with engine.begin() as connection:
        if connection.dialect.name == "postgresql":
            # several service processes starting at once on one database migrate one after the other:
            # the lock lasts until this transaction commits (PostgreSQL's DDL is transactional), and
            # the next process then finds the schema at head
            connection.execute(text("SELECT pg_advisory_xact_lock(:key)"), {"key": MIGRATION_LOCK})
        cfg.attributes["connection"] = connection
        command.upgrade(cfg, "head")
