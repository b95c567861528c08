"""A change counter per scene for what keeps the tree revision: assignments and identity-only pushes.

Several service processes may share one database; each compares ``(revision, assign_revision)`` of a
scene with what it holds in memory at every request (one SELECT) and reloads what is behind.

Revision ID: 0003
Revises: 0002
Create Date: 2026-12-02
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0003"
down_revision = "0002"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("scenes") as batch:
        batch.add_column(sa.Column("assign_revision", sa.Integer, nullable=False, server_default="0"))


def downgrade() -> None:
    with op.batch_alter_table("scenes") as batch:
        batch.drop_column("assign_revision")
