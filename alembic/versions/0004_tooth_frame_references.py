"""tooth_frame_references: a campaign's tooth frame without a tachometer (issue 11)

Revision ID: 0004_tooth_frames
Revises: 0003_quality
Create Date: 2026-11-25 02:30:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = '0004_tooth_frames'
down_revision: str | None = '0003_quality'
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table('tooth_frame_references',
    sa.Column('id', sa.Integer(), nullable=False),
    sa.Column('campaign_id', sa.Integer(), nullable=False),
    sa.Column('channel', sa.String(length=200), nullable=False),
    sa.Column('frame', sa.String(length=16), nullable=False),
    sa.Column('record_sha256', sa.String(length=64), nullable=False),
    sa.Column('records', sa.Integer(), nullable=False),
    sa.Column('pinion_position', sa.Double(), nullable=False),
    sa.Column('pinion_fingerprint', sa.LargeBinary(), nullable=False),
    sa.Column('gear_fingerprint', sa.LargeBinary(), nullable=True),
    sa.Column('updated_at', sa.DateTime(timezone=True), nullable=False),
    sa.CheckConstraint("frame IN ('tachometer', 'mesh_phase')", name=op.f('ck_tooth_frame_references_frame')),
    sa.ForeignKeyConstraint(['campaign_id'], ['campaigns.id'], name=op.f('fk_tooth_frame_references_campaign_id_campaigns'), ondelete='CASCADE'),
    sa.PrimaryKeyConstraint('id', name=op.f('pk_tooth_frame_references')),
    sa.UniqueConstraint('campaign_id', 'channel', name=op.f('uq_tooth_frame_references_campaign_id_channel'))
    )


def downgrade() -> None:
    op.drop_table('tooth_frame_references')
