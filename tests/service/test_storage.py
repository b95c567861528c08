"""Storage: the Alembic migration builds exactly the schema the code declares; SQLite runs in WAL mode;
settings come from LUMENLINK_* variables; mesh files are content-addressed and written atomically."""

from __future__ import annotations

import numpy as np
import pytest
import sqlalchemy as sa
from alembic.autogenerate import compare_metadata
from alembic.migration import MigrationContext
from service_helpers import glb, grid_mesh

from service import db
from service.config import Settings
from service.errors import BadRequest, Invalid, NotFound
from service.meshes import MeshStore


def test_migration_matches_the_declared_schema(tmp_path) -> None:
    engine = db.open_engine(f"sqlite:///{tmp_path / 'x.sqlite3'}")
    with engine.connect() as conn:
        diff = compare_metadata(MigrationContext.configure(conn), db.metadata)
        assert diff == [], diff
        assert conn.execute(sa.text("PRAGMA journal_mode")).scalar() == "wal"
        assert conn.execute(sa.text("PRAGMA foreign_keys")).scalar() == 1
        assert conn.execute(sa.text("SELECT version_num FROM alembic_version")).scalar() == "0012"


def _alembic(engine, step: str, revision: str) -> None:
    from alembic import command
    from alembic.config import Config

    cfg = Config(str(db.MIGRATIONS / "alembic.ini"))
    cfg.set_main_option("script_location", str(db.MIGRATIONS))
    with engine.begin() as connection:
        cfg.attributes["connection"] = connection
        getattr(command, step)(cfg, revision)


OLDER_BODIES = {   # node -> (a body stored before migration 0012, what it holds after)
    "glass": ({"type": "dielectric", "ior": 1.5}, {"type": "dielectric", "ior": 1.5}),
    "milky": ({"type": "dielectric", "ior": 1.49, "absorption_per_m": 0.2, "scattering_per_m": 3.0, "g": 0.7},
              {"type": "dielectric", "ior": 1.49, "absorption_per_m": 0.2, "scattering_per_m": 3.0, "g": 0.7}),
    "frosted": ({"type": "rough_dielectric", "ior": 1.5, "alpha": 0.2, "absorption_per_m": 1.0},
                {"type": "dielectric", "ior": 1.5, "alpha": 0.2, "absorption_per_m": 1.0}),
    "wall": ({"type": "lambertian", "reflectance": 0.5}, {"type": "lambertian", "reflectance": 0.5}),
}


def test_migration_0012_stores_rough_dielectrics_as_dielectrics(tmp_path) -> None:
    """Bodies stored under 0011 come out of 0012 as the tracer reads them today (the same spec as the older body
    read through `upgrade_body`), the others untouched; downgrading gives the stored bodies back."""
    from tracer.optics.surfaces.dispatch import material_spec

    engine = db.open_engine(f"sqlite:///{tmp_path / 'x.sqlite3'}", migrate=False)
    _alembic(engine, "upgrade", "0011")
    with engine.begin() as conn:
        conn.execute(sa.insert(db.scenes).values(id="s", name="s", revision=0))
        for node, (old, _) in OLDER_BODIES.items():
            conn.execute(sa.insert(db.materials).values(scene_id="s", node=node, body=old))
    _alembic(engine, "upgrade", "head")
    with engine.connect() as conn:
        stored = dict(conn.execute(sa.select(db.materials.c.node, db.materials.c.body)).all())
    assert stored == {node: new for node, (_, new) in OLDER_BODIES.items()}
    for node, (old, new) in OLDER_BODIES.items():
        assert material_spec(new) == material_spec(old), node
    _alembic(engine, "downgrade", "0011")
    with engine.connect() as conn:
        assert dict(conn.execute(sa.select(db.materials.c.node, db.materials.c.body)).all()) == \
            {node: old for node, (old, _) in OLDER_BODIES.items()}


def test_migrating_twice_is_harmless(tmp_path) -> None:
    url = f"sqlite:///{tmp_path / 'x.sqlite3'}"
    db.open_engine(url).dispose()
    engine = db.open_engine(url)
    with engine.connect() as conn:
        assert set(sa.inspect(conn).get_table_names()) >= {"scenes", "revisions", "nodes", "geometries", "materials",
                                                          "lights", "sensors", "sim_objects", "node_identity"}


def test_settings_from_the_environment(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("LUMENLINK_DATA_DIR", str(tmp_path))
    monkeypatch.setenv("LUMENLINK_MAX_BODY_BYTES", "1234")
    s = Settings()
    assert s.data_dir == tmp_path and s.max_body_bytes == 1234
    assert s.resolved_database_url() == f"sqlite:///{(tmp_path / 'lumenlink.sqlite3').resolve()}"
    monkeypatch.setenv("LUMENLINK_DATABASE_URL", "postgresql://u@h/db")
    assert Settings().resolved_database_url() == "postgresql://u@h/db"
    with pytest.raises(ValueError):
        Settings(max_body_bytes=0)
    with pytest.raises(ValueError):
        Settings(colour="red")  # unknown settings are refused too


def test_mesh_store_round_trip_and_refusals(tmp_path) -> None:
    store = MeshStore(tmp_path / "meshes")
    v, f = grid_mesh(3)
    gid, data = glb(v, f)
    mesh = store.validate_upload(gid, data)
    store.write(gid, data, mesh)
    back = store.load(gid)
    assert back.vertices.dtype == np.float32 and back.triangles.dtype == np.uint32 and back.normals is None
    np.testing.assert_array_equal(back.vertices, v.astype(np.float32))
    np.testing.assert_array_equal(back.triangles, f)
    assert store.glb(gid) == data
    assert sorted(p.name for p in (tmp_path / "meshes").iterdir()) == [f"{gid}.glb", f"{gid}.npz"]
    with pytest.raises(BadRequest, match="hash"):
        store.validate_upload("0" * 64, data)
    with pytest.raises(Invalid, match="64 lowercase hex"):
        store.load("../../etc/passwd")
    with pytest.raises(NotFound):
        store.load("0" * 64)
