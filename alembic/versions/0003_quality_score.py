"""data quality of a result: score and rejections per result version and per channel (issue 10)

Additive: nullable / defaulted columns only, so older rows keep working (their score is NULL).

Revision ID: 0003_quality
Revises: 0002
Create Date: 2026-11-25 02:30:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = '0003_quality'
down_revision: str | None = '0002'
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table('result_versions', schema=None) as batch_op:
        batch_op.add_column(sa.Column('quality_score', sa.Double(), nullable=True))
        batch_op.add_column(
            sa.Column('quality', sa.JSON(), nullable=False, server_default='{}')
        )
    with op.batch_alter_table('channel_results', schema=None) as batch_op:
        batch_op.add_column(
            sa.Column('quality', sa.JSON(), nullable=False, server_default='{}')
        )


def downgrade() -> None:
    with op.batch_alter_table('channel_results', schema=None) as batch_op:
        batch_op.drop_column('quality')
    with op.batch_alter_table('result_versions', schema=None) as batch_op:
        batch_op.drop_column('quality')
        batch_op.drop_column('quality_score')
