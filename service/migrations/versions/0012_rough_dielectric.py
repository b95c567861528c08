"""Stored ``rough_dielectric`` material bodies as ``dielectric`` ones with their ``alpha`` (issue 55: the rough
dielectric folded into the dielectric, as pbrt's dielectric material takes a roughness). The fields are the same; only
the type changes. `tracer.optics.surfaces.dielectric.upgrade` reads such a body at run time too, for anything not
stored.

Revision ID: 0012
Revises: 0011
Create Date: 2026-12-07
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0012"
down_revision = "0011"
branch_labels = None
depends_on = None

materials = sa.table("materials", sa.column("scene_id", sa.String), sa.column("node", sa.String),
                     sa.column("body", sa.JSON))


def _retype(old: str, new: str, rough_only: bool) -> None:
    conn = op.get_bind()
    for scene_id, node, body in conn.execute(sa.select(materials.c.scene_id, materials.c.node, materials.c.body)):
        if isinstance(body, dict) and body.get("type") == old and (not rough_only or (body.get("alpha") or 0) > 0):
            conn.execute(materials.update().where(materials.c.scene_id == scene_id).where(materials.c.node == node)
                         .values(body={**body, "type": new}))


def upgrade() -> None:
    _retype("rough_dielectric", "dielectric", rough_only=False)


def downgrade() -> None:
    _retype("dielectric", "rough_dielectric", rough_only=True)   # a rough dielectric was a kind of its own
