"""tooth_frame_references.speed_rpm: the campaign's confirmed speed, a tach-less record's hint (issue 11)

Additive only: existing references get NULL (no learned speed; the next accepted record sets it).

Revision ID: 0007_tooth_frame_speed
Revises: 0006_detection
Create Date: 2026-11-28 12:45:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = '0007_tooth_frame_speed'
down_revision: str | None = '0006_detection'
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.add_column('tooth_frame_references', sa.Column('speed_rpm', sa.Double(), nullable=True))


def downgrade() -> None:
    op.drop_column('tooth_frame_references', 'speed_rpm')
