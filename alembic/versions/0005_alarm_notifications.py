"""alarm notifications: per-rig webhooks, the notification outbox and its delivery attempts

Revision ID: 0005_alarm_notifications
Revises: 0004_tooth_frames
Create Date: 2026-11-25 02:20:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op


revision: str = "0005_alarm_notifications"
down_revision: str | None = "0004_tooth_frames"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "alarm_webhooks",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("rig_id", sa.Integer(), nullable=False),
        sa.Column("url", sa.String(length=2000), nullable=False),
        sa.Column("description", sa.String(length=200), nullable=False),
        sa.Column("enabled", sa.Boolean(), nullable=False),
        sa.Column("created_by", sa.String(length=200), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(
            ["rig_id"], ["rigs.id"], name=op.f("fk_alarm_webhooks_rig_id_rigs"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_alarm_webhooks")),
        sa.UniqueConstraint("rig_id", "url", name=op.f("uq_alarm_webhooks_rig_id_url")),
    )
    op.create_index(op.f("ix_alarm_webhooks_rig_id"), "alarm_webhooks", ["rig_id"], unique=False)
    op.create_table(
        "alarm_notifications",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("rig_id", sa.Integer(), nullable=False),
        sa.Column("alarm_id", sa.Integer(), nullable=True),
        sa.Column("webhook_id", sa.Integer(), nullable=True),
        sa.Column("url", sa.String(length=2000), nullable=False),
        sa.Column("payload", sa.JSON(), nullable=False),
        sa.Column("status", sa.String(length=16), nullable=False),
        sa.Column("attempts", sa.Integer(), nullable=False),
        sa.Column("next_attempt_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("last_error", sa.Text(), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("delivered_at", sa.DateTime(timezone=True), nullable=True),
        sa.CheckConstraint(
            "status IN ('pending', 'delivered', 'failed')",
            name=op.f("ck_alarm_notifications_status"),
        ),
        sa.ForeignKeyConstraint(
            ["alarm_id"], ["alarms.id"], name=op.f("fk_alarm_notifications_alarm_id_alarms"),
            ondelete="SET NULL",
        ),
        sa.ForeignKeyConstraint(
            ["rig_id"], ["rigs.id"], name=op.f("fk_alarm_notifications_rig_id_rigs"),
            ondelete="CASCADE",
        ),
        sa.ForeignKeyConstraint(
            ["webhook_id"], ["alarm_webhooks.id"],
            name=op.f("fk_alarm_notifications_webhook_id_alarm_webhooks"), ondelete="SET NULL",
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_alarm_notifications")),
    )
    op.create_index(
        op.f("ix_alarm_notifications_alarm_id"), "alarm_notifications", ["alarm_id"], unique=False
    )
    op.create_index(
        op.f("ix_alarm_notifications_rig_id"), "alarm_notifications", ["rig_id"], unique=False
    )
    op.create_index(
        "ix_alarm_notifications_status_next_attempt_at",
        "alarm_notifications",
        ["status", "next_attempt_at"],
        unique=False,
    )
    op.create_table(
        "notification_attempts",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("notification_id", sa.Integer(), nullable=False),
        sa.Column("at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("status_code", sa.Integer(), nullable=True),
        sa.Column("error", sa.Text(), nullable=False),
        sa.Column("duration_ms", sa.Double(), nullable=False),
        sa.ForeignKeyConstraint(
            ["notification_id"], ["alarm_notifications.id"],
            name=op.f("fk_notification_attempts_notification_id_alarm_notifications"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_notification_attempts")),
    )
    op.create_index(
        op.f("ix_notification_attempts_notification_id"),
        "notification_attempts",
        ["notification_id"],
        unique=False,
    )


def downgrade() -> None:
    op.drop_index(op.f("ix_notification_attempts_notification_id"), table_name="notification_attempts")
    op.drop_table("notification_attempts")
    op.drop_index("ix_alarm_notifications_status_next_attempt_at", table_name="alarm_notifications")
    op.drop_index(op.f("ix_alarm_notifications_rig_id"), table_name="alarm_notifications")
    op.drop_index(op.f("ix_alarm_notifications_alarm_id"), table_name="alarm_notifications")
    op.drop_table("alarm_notifications")
    op.drop_index(op.f("ix_alarm_webhooks_rig_id"), table_name="alarm_webhooks")
    op.drop_table("alarm_webhooks")
