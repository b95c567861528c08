"""Node identity records: per scene and node uuid, the product name and shape signature the CAD adapter matches by.

Revision ID: 0002
Revises: 0001
Create Date: 2026-11-28
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "node_identity",
        sa.Column("scene_id", sa.String(36), sa.ForeignKey("scenes.id", ondelete="CASCADE"), primary_key=True),
        sa.Column("uuid", sa.String(36), primary_key=True),
        sa.Column("product", sa.String(500), nullable=True),
        sa.Column("signature", sa.JSON, nullable=True),
    )


def downgrade() -> None:
    op.drop_table("node_identity")
