"""Alarm notifications: the rigs' webhooks, and the outbox with every delivery attempt."""

from __future__ import annotations

import datetime as dt
from typing import TYPE_CHECKING, Annotated, Any, Literal, cast

import sqlalchemy as sa
from fastapi import APIRouter, Path, Query, Response
from pydantic import BaseModel, ConfigDict, Field

from service.convert import rig_by_name
from service.deps import DbSession, OperatorKey
from service.routers.common import Limit, Offset, RigFilter, RigName, errors
from service.schemas import NO_CONTROL_CHARACTERS
from storage.outbox import NotificationRepository, global_webhook_url
from storage.outbox_delivery import kick
from storage.repositories import AuditRepository, RigRepository

if TYPE_CHECKING:
    from sqlalchemy.orm import Session

    from storage.models import AlarmNotification, AlarmWebhook

NotificationStatus = Literal["pending", "delivered", "failed"]
"""As the table's CHECK constraint allows them (``storage.models.NOTIFICATION_STATUSES``)."""

router = APIRouter(prefix="/api/v1", tags=["notifications"])

WebhookId = Annotated[int, Path(ge=1, le=2**31 - 1, description="Webhook id.")]
NotificationId = Annotated[int, Path(ge=1, le=2**31 - 1, description="Notification id.")]


class WebhookIn(BaseModel):
    model_config = ConfigDict(extra="forbid")
    url: str = Field(
        min_length=8, max_length=2000, pattern=r"^(https?://|mailto:)[^\s\x00-\x1f]+$",
        description="An http(s) URL (the change is POSTed as JSON) or mailto:ADDRESS (sent "
        "by e-mail through GEARWATCH_SMTP_URL).",
        examples=["https://chat.example.org/hooks/rig-a"],
    )
    description: str = Field(
        default="", max_length=200, pattern=NO_CONTROL_CHARACTERS, examples=["night shift chat"]
    )


class WebhookOut(BaseModel):
    id: int
    rig_id: str
    url: str
    description: str
    enabled: bool
    created_by: str
    created_at: dt.datetime


class WebhookList(BaseModel):
    rig_id: str
    global_webhook: bool = Field(
        description="Whether GEARWATCH_ALARM_WEBHOOK_URL is set in this process (every rig's "
        "changes go there too)."
    )
    items: list[WebhookOut]


class AttemptOut(BaseModel):
    at: dt.datetime
    status_code: int | None
    error: str
    duration_ms: float


class NotificationOut(BaseModel):
    id: int
    rig_id: str
    alarm_id: int | None
    webhook_id: int | None = Field(description="null: the global webhook.")
    url: str
    status: NotificationStatus
    attempts: int
    next_attempt_at: dt.datetime
    last_error: str
    created_at: dt.datetime
    delivered_at: dt.datetime | None
    payload: dict[str, Any]
    attempt_log: list[AttemptOut] = Field(default_factory=list)


class NotificationList(BaseModel):
    items: list[NotificationOut]


def _webhook_out(rig: str, hook: AlarmWebhook) -> WebhookOut:
    return WebhookOut(
        id=hook.id, rig_id=rig, url=hook.url, description=hook.description,
        enabled=hook.enabled, created_by=hook.created_by, created_at=hook.created_at,
    )


def _notification_out(db: Session, row: AlarmNotification, names: dict[int, str]) -> NotificationOut:
    return NotificationOut(
        id=row.id, rig_id=names.get(row.rig_id, str(row.rig_id)), alarm_id=row.alarm_id,
        webhook_id=row.webhook_id, url=row.url, attempts=row.attempts,
        status=cast(NotificationStatus, row.status),  # a CHECK constraint in the table; pydantic checks it too
        next_attempt_at=row.next_attempt_at, last_error=row.last_error,
        created_at=row.created_at, delivered_at=row.delivered_at, payload=row.payload,
        attempt_log=[
            AttemptOut(at=a.at, status_code=a.status_code, error=a.error,
                       duration_ms=a.duration_ms)
            for a in NotificationRepository(db).attempts(row.id)
        ],
    )


@router.get(
    "/rigs/{rig_id}/webhooks",
    response_model=WebhookList,
    summary="The rig's alarm webhooks (operator: a webhook URL often holds a token)",
    responses=errors(401, 403, 404, 422),
)
def list_webhooks(rig_id: RigName, db: DbSession, _caller: OperatorKey) -> WebhookList:
    rig = rig_by_name(db, rig_id)
    hooks = NotificationRepository(db).webhooks(rig.id)
    return WebhookList(
        rig_id=rig.name,
        global_webhook=global_webhook_url() is not None,
        items=[_webhook_out(rig.name, h) for h in hooks],
    )


@router.post(
    "/rigs/{rig_id}/webhooks",
    response_model=WebhookOut,
    status_code=201,
    summary="Add a webhook to the rig (operator)",
    description="Every alarm state change of the rig (opened, escalated, acknowledged, "
    "cleared) is POSTed to the URL as JSON: rig_id, campaign_id, channel, indicator, tooth "
    "(null for a whole-record indicator), state, raised_at, record_id, record_label, value, "
    "score, unit, dashboard_url … Audited.",
    responses=errors(401, 403, 404, 409, 422),
)
def add_webhook(
    rig_id: RigName, body: WebhookIn, db: DbSession, caller: OperatorKey
) -> WebhookOut:
    rig = rig_by_name(db, rig_id)
    hook = NotificationRepository(db).add_webhook(
        rig.id, body.url, description=body.description, created_by=caller.who
    )
    AuditRepository(db).add(
        who=caller.who, action="webhook.add", target=f"rig:{rig.name}/webhook:{hook.id}",
        details={"url": body.url},
    )
    db.commit()
    return _webhook_out(rig.name, hook)


@router.delete(
    "/rigs/{rig_id}/webhooks/{webhook_id}",
    status_code=204,
    summary="Remove a webhook (operator)",
    responses=errors(401, 403, 404, 422),
)
def delete_webhook(
    rig_id: RigName, webhook_id: WebhookId, db: DbSession, caller: OperatorKey
) -> Response:
    rig = rig_by_name(db, rig_id)
    NotificationRepository(db).delete_webhook(rig.id, webhook_id)
    AuditRepository(db).add(
        who=caller.who, action="webhook.delete", target=f"rig:{rig.name}/webhook:{webhook_id}"
    )
    db.commit()
    return Response(status_code=204)


@router.get(
    "/notifications",
    response_model=NotificationList,
    summary="Alarm notifications (the outbox), newest first, with every delivery attempt "
    "(operator)",
    responses=errors(401, 403, 404, 422),
)
def list_notifications(
    db: DbSession,
    _caller: OperatorKey,
    rig_id: RigFilter = None,
    alarm_id: Annotated[int | None, Query(ge=1, le=2**31 - 1)] = None,
    status: Annotated[NotificationStatus | None, Query()] = None,
    limit: Limit = 100,
    offset: Offset = 0,
) -> NotificationList:
    rig_pk = None if rig_id is None else rig_by_name(db, rig_id).id
    rows = NotificationRepository(db).list(
        rig_id=rig_pk, alarm_id=alarm_id, status=status, limit=limit, offset=offset
    )
    names = {r.id: r.name for r in RigRepository(db).list()}
    return NotificationList(items=[_notification_out(db, r, names) for r in rows])


@router.post(
    "/notifications/{notification_id}/retry",
    response_model=NotificationOut,
    summary="Queue a failed notification again (operator)",
    responses=errors(401, 403, 404, 409, 422),
)
def retry_notification(
    notification_id: NotificationId, db: DbSession, caller: OperatorKey
) -> NotificationOut:
    row = NotificationRepository(db).retry(notification_id)
    AuditRepository(db).add(
        who=caller.who, action="notification.retry", target=f"notification:{notification_id}"
    )
    db.commit()
    bind = db.get_bind()
    kick(bind if isinstance(bind, sa.Engine) else bind.engine)
    names = {r.id: r.name for r in RigRepository(db).list()}
    return _notification_out(db, row, names)
