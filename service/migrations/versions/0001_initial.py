"""Initial schema: scenes, revisions, nodes, geometries, materials, lights, sensors, sim_objects.

Revision ID: 0001
Revises:
Create Date: 2026-11-21
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None


def _created() -> sa.Column:
    return sa.Column("created_at", sa.DateTime(timezone=True), nullable=False, server_default=sa.func.now())


def upgrade() -> None:
    op.create_table(
        "scenes",
        sa.Column("id", sa.String(36), primary_key=True),
        sa.Column("name", sa.String(200), nullable=False, unique=True),
        sa.Column("revision", sa.Integer, nullable=False),
        sa.Column("length_unit", sa.String(8), nullable=True),
        sa.Column("source", sa.JSON, nullable=True),
        _created(),
        sa.Column("updated_at", sa.DateTime(timezone=True), nullable=False, server_default=sa.func.now()),
    )
    op.create_table(
        "revisions",
        sa.Column("scene_id", sa.String(36), sa.ForeignKey("scenes.id", ondelete="CASCADE"), primary_key=True),
        sa.Column("revision", sa.Integer, primary_key=True),
        _created(),
        sa.Column("summary", sa.JSON, nullable=False),
    )
    op.create_table(
        "nodes",
        sa.Column("scene_id", sa.String(36), sa.ForeignKey("scenes.id", ondelete="CASCADE"), primary_key=True),
        sa.Column("uuid", sa.String(36), primary_key=True),
        sa.Column("position", sa.Float, nullable=False),
        sa.Column("parent", sa.String(36), nullable=True),
        sa.Column("name", sa.String(500), nullable=False),
        sa.Column("transform", sa.LargeBinary(128), nullable=False),
        sa.Column("geometry", sa.String(64), nullable=True),
        sa.Column("color", sa.JSON, nullable=True),
    )
    op.create_table(
        "geometries",
        sa.Column("id", sa.String(64), primary_key=True),
        sa.Column("n_vertices", sa.Integer, nullable=False),
        sa.Column("n_triangles", sa.Integer, nullable=False),
        sa.Column("has_normals", sa.Boolean, nullable=False),
        sa.Column("size_bytes", sa.Integer, nullable=False),
        _created(),
    )
    op.create_table(
        "materials",
        sa.Column("scene_id", sa.String(36), sa.ForeignKey("scenes.id", ondelete="CASCADE"), primary_key=True),
        sa.Column("node", sa.String(36), primary_key=True),
        sa.Column("body", sa.JSON, nullable=False),
    )
    for name in ("lights", "sensors", "sim_objects"):
        op.create_table(
            name,
            sa.Column("id", sa.String(36), primary_key=True),
            sa.Column("scene_id", sa.String(36), sa.ForeignKey("scenes.id", ondelete="CASCADE"), nullable=False),
            sa.Column("body", sa.JSON, nullable=False),
            _created(),
        )
        op.create_index(f"ix_{name}_scene_id", name, ["scene_id"])


def downgrade() -> None:
    for name in ("sim_objects", "sensors", "lights"):
        op.drop_index(f"ix_{name}_scene_id", table_name=name)
        op.drop_table(name)
    for name in ("materials", "geometries", "nodes", "revisions", "scenes"):
        op.drop_table(name)
