"""detection statistics: short-campaign baselines and CUSUM on alarm rules, alarm evidence (issue 10)

Additive only. Per-tooth ``mci_depth_se`` and ``score`` need no schema change: they are rows of
``tooth_indicators`` (result × channel × tooth × indicator).

Revision ID: 0006_detection
Revises: 0005_alarm_notifications
Create Date: 2026-11-25 02:30:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = '0006_detection'
down_revision: str | None = '0005_alarm_notifications'
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.add_column('alarm_rules', sa.Column('min_baseline_records', sa.Integer(), nullable=True))
    op.add_column('alarm_rules', sa.Column('cusum_reference', sa.Double(), nullable=True))
    op.add_column('alarm_rules', sa.Column('cusum_limit', sa.Double(), nullable=True))
    op.add_column('alarms', sa.Column('evidence', sa.String(length=16), nullable=True))


def downgrade() -> None:
    op.drop_column('alarms', 'evidence')
    op.drop_column('alarm_rules', 'cusum_limit')
    op.drop_column('alarm_rules', 'cusum_reference')
    op.drop_column('alarm_rules', 'min_baseline_records')
