"""The alarm notification outbox: every alarm state change becomes one row per destination,
written in the same transaction as the change.

:func:`queue_alarm_notifications` runs before each flush of a session made by
:func:`storage.db.session_factory`: for every new :class:`~storage.models.AlarmEvent` (an
alarm opened, escalated, acknowledged or cleared — whoever made it: evaluation, an operator, a
rule change) it adds an :class:`~storage.models.AlarmNotification` for the global webhook
(``GEARWATCH_ALARM_WEBHOOK_URL``) and for each enabled webhook of the alarm's rig. Nothing is
sent here: :mod:`storage.outbox_delivery` delivers after the commit, so a rolled-back change notifies
nobody and a committed one cannot be lost.
"""

from __future__ import annotations

import builtins
import datetime as dt
import os
from typing import Any
from urllib.parse import quote, urlsplit

import sqlalchemy as sa
from sqlalchemy.orm import Session

from gearwatch.floor.errors import Conflict, InputError, NotFound
from gearwatch.floor.indicators import indicator_info, indicator_unit
from storage.models import (
    Alarm,
    AlarmEvent,
    AlarmNotification,
    AlarmWebhook,
    Campaign,
    Channel,
    NotificationAttempt,
    Record,
    Rig,
    utcnow,
)
from storage.repositories import json_safe

GLOBAL_WEBHOOK_ENV = "GEARWATCH_ALARM_WEBHOOK_URL"
GLOBAL_EMAIL_ENV = "GEARWATCH_ALARM_EMAIL_TO"
"""Comma-separated addresses that receive every alarm state change by e-mail (SMTP settings:
:mod:`storage.outbox_delivery`)."""
DASHBOARD_URL_ENV = "GEARWATCH_DASHBOARD_URL"
DEFAULT_DASHBOARD_URL = "http://127.0.0.1:8000/"
QUEUED_FLAG = "gearwatch.outbox.queued"
"""``session.info`` key set when a flush queued notifications (delivery is kicked on commit)."""


def global_webhook_url() -> str | None:
    url = os.environ.get(GLOBAL_WEBHOOK_ENV, "").strip()
    return url or None


def global_destinations() -> builtins.list[str]:
    """The global webhook and the global e-mail recipients (as ``mailto:`` URLs)."""
    found = [url] if (url := global_webhook_url()) else []
    for address in os.environ.get(GLOBAL_EMAIL_ENV, "").split(","):
        if address.strip():
            found.append(f"mailto:{address.strip()}")
    return found


def dashboard_link(rig_name: str, alarm_id: int) -> str:
    """The dashboard opened on the rig and the alarm (``GEARWATCH_DASHBOARD_URL``)."""
    base = os.environ.get(DASHBOARD_URL_ENV, "").strip() or DEFAULT_DASHBOARD_URL
    if not base.endswith("/"):
        base += "/"
    return f"{base}#rig={quote(rig_name, safe='')}&alarm={alarm_id}"


def check_url(url: str) -> str:
    """An http(s) URL or a ``mailto:`` address, else :class:`InputError`."""
    parts = urlsplit(url)
    if parts.scheme == "mailto" and "@" in parts.path:
        return url
    if parts.scheme not in ("http", "https") or not parts.netloc:
        raise InputError(f"a webhook needs an http(s) URL or a mailto: address, got {url!r}")
    return url


def _iso(value: dt.datetime | None) -> str | None:
    return None if value is None else value.astimezone(dt.UTC).isoformat().replace("+00:00", "Z")


def alarm_payload(session: Session, alarm: Alarm, event: AlarmEvent) -> dict[str, Any]:
    """The JSON body of one alarm state change."""
    rig = session.get(Rig, alarm.rig_id)
    channel = session.get(Channel, alarm.channel_id)
    campaign = session.get(Campaign, channel.campaign_id) if channel is not None else None
    record_id = event.record_id if event.record_id is not None else alarm.raised_record_id
    record = session.get(Record, record_id) if record_id is not None else None
    try:
        whole = indicator_info(alarm.indicator).scope == "record"
        unit = indicator_unit(alarm.indicator, channel.unit if channel else "")
    except ValueError:
        whole, unit = alarm.tooth == 0, ""
    rig_name = rig.name if rig is not None else str(alarm.rig_id)
    return {
        "event": "alarm.state_changed",
        "alarm_id": alarm.id,
        "rig_id": rig_name,
        "campaign_id": campaign.name if campaign is not None else None,
        "channel": channel.name if channel is not None else None,
        "indicator": alarm.indicator,
        "tooth": None if whole or alarm.tooth == 0 else alarm.tooth,
        "state": event.state,
        "severity": alarm.severity,
        "raised_at": _iso(alarm.raised_at),
        "changed_at": _iso(event.at),
        "record_id": record_id,
        "record_label": record.label if record is not None else None,
        "record_taken_at": _iso(record.taken_at) if record is not None else None,
        "value": event.value,
        "score": event.score,
        "unit": unit,
        "baseline_centre": alarm.baseline_centre,
        "baseline_spread": alarm.baseline_spread,
        "who": event.who,
        "comment": event.comment,
        "dashboard_url": dashboard_link(rig_name, alarm.id),
        "api_url": f"/api/v1/alarms/{alarm.id}",
    }


def queue_alarm_notifications(session: Session, _flush_context: Any, _instances: Any) -> None:
    """``before_flush`` hook: an outbox row per new alarm event and destination."""
    events = [obj for obj in session.new if isinstance(obj, AlarmEvent)]
    if not events:
        return
    global_urls = global_destinations()
    with session.no_autoflush:
        hooks: dict[int, builtins.list[AlarmWebhook]] = {}
        for event in events:
            alarm = event.alarm if "alarm" in event.__dict__ else None
            if alarm is None:
                alarm = session.get(Alarm, event.alarm_id)
            if alarm is None:
                continue
            if alarm.rig_id not in hooks:
                hooks[alarm.rig_id] = list(
                    session.scalars(
                        sa.select(AlarmWebhook).where(
                            AlarmWebhook.rig_id == alarm.rig_id, AlarmWebhook.enabled.is_(True)
                        )
                    )
                )
            destinations: builtins.list[tuple[int | None, str]] = [
                (hook.id, hook.url) for hook in hooks[alarm.rig_id]
            ]
            destinations[:0] = [(None, url) for url in global_urls]
            if not destinations:
                continue
            payload = json_safe(alarm_payload(session, alarm, event))
            now = utcnow()
            for webhook_id, url in destinations:
                session.add(
                    AlarmNotification(
                        rig_id=alarm.rig_id,
                        alarm_id=alarm.id,
                        webhook_id=webhook_id,
                        url=url,
                        payload=payload,
                        status="pending",
                        attempts=0,
                        next_attempt_at=now,
                        last_error="",
                        created_at=now,
                    )
                )
            session.info[QUEUED_FLAG] = True


class NotificationRepository:
    """Webhooks of the rigs, and the outbox with its delivery attempts."""

    def __init__(self, session: Session) -> None:
        self.session = session

    # -- webhooks ---------------------------------------------------------------------------
    def webhooks(self, rig_id: int) -> builtins.list[AlarmWebhook]:
        query = sa.select(AlarmWebhook).where(AlarmWebhook.rig_id == rig_id)
        return list(self.session.scalars(query.order_by(AlarmWebhook.id)))

    def add_webhook(
        self, rig_id: int, url: str, *, description: str = "", created_by: str = ""
    ) -> AlarmWebhook:
        check_url(url)
        exists = self.session.scalar(
            sa.select(AlarmWebhook.id).where(AlarmWebhook.rig_id == rig_id, AlarmWebhook.url == url)
        )
        if exists is not None:
            raise Conflict(f"the rig already has a webhook to {url}")
        hook = AlarmWebhook(
            rig_id=rig_id, url=url, description=description, enabled=True, created_by=created_by
        )
        self.session.add(hook)
        self.session.flush()
        return hook

    def webhook(self, rig_id: int, webhook_id: int) -> AlarmWebhook:
        hook = self.session.get(AlarmWebhook, webhook_id)
        if hook is None or hook.rig_id != rig_id:
            raise NotFound(f"webhook {webhook_id} not found")
        return hook

    def delete_webhook(self, rig_id: int, webhook_id: int) -> None:
        self.session.delete(self.webhook(rig_id, webhook_id))
        self.session.flush()

    # -- outbox -----------------------------------------------------------------------------
    def list(
        self,
        *,
        rig_id: int | None = None,
        alarm_id: int | None = None,
        status: str | None = None,
        limit: int | None = 100,
        offset: int = 0,
    ) -> builtins.list[AlarmNotification]:
        """Newest first."""
        query = sa.select(AlarmNotification)
        if rig_id is not None:
            query = query.where(AlarmNotification.rig_id == rig_id)
        if alarm_id is not None:
            query = query.where(AlarmNotification.alarm_id == alarm_id)
        if status is not None:
            query = query.where(AlarmNotification.status == status)
        query = query.order_by(AlarmNotification.id.desc()).offset(offset)
        if limit is not None:
            query = query.limit(limit)
        return list(self.session.scalars(query))

    def get(self, notification_id: int) -> AlarmNotification:
        row = self.session.get(AlarmNotification, notification_id)
        if row is None:
            raise NotFound(f"notification {notification_id} not found")
        return row

    def attempts(self, notification_id: int) -> builtins.list[NotificationAttempt]:
        query = (
            sa.select(NotificationAttempt)
            .where(NotificationAttempt.notification_id == notification_id)
            .order_by(NotificationAttempt.id)
        )
        return list(self.session.scalars(query))

    def due(self, now: dt.datetime, limit: int = 50) -> builtins.list[AlarmNotification]:
        """Pending notifications whose next attempt is due, oldest first."""
        query = (
            sa.select(AlarmNotification)
            .where(AlarmNotification.status == "pending", AlarmNotification.next_attempt_at <= now)
            .order_by(AlarmNotification.next_attempt_at, AlarmNotification.id)
            .limit(limit)
        )
        return list(self.session.scalars(query))

    def next_due_at(self) -> dt.datetime | None:
        """When the earliest pending notification is due (``None``: nothing pending)."""
        return self.session.scalar(
            sa.select(sa.func.min(AlarmNotification.next_attempt_at)).where(
                AlarmNotification.status == "pending"
            )
        )

    def claim(self, notification_id: int, seen_due_at: dt.datetime, until: dt.datetime) -> bool:
        """Take a due notification for one attempt (its next attempt moves to ``until``), unless
        another process took it since it was read: two deliverers never send it twice."""
        result = self.session.execute(
            sa.update(AlarmNotification)
            .where(
                AlarmNotification.id == notification_id,
                AlarmNotification.status == "pending",
                AlarmNotification.next_attempt_at == seen_due_at,
            )
            .values(next_attempt_at=until),
            execution_options={"synchronize_session": False},
        )
        return bool(getattr(result, "rowcount", 0) == 1)

    def record_attempt(
        self,
        notification: AlarmNotification,
        *,
        at: dt.datetime,
        status_code: int | None,
        error: str,
        duration_ms: float,
        delivered: bool,
        retry_at: dt.datetime | None,
    ) -> NotificationAttempt:
        """Log one attempt; the notification becomes ``delivered``, stays ``pending`` until
        ``retry_at``, or ``failed`` (no ``retry_at``)."""
        attempt = NotificationAttempt(
            notification_id=notification.id,
            at=at,
            status_code=status_code,
            error=error,
            duration_ms=duration_ms,
        )
        self.session.add(attempt)
        notification.attempts += 1
        notification.last_error = error
        if delivered:
            notification.status = "delivered"
            notification.delivered_at = at
        elif retry_at is not None:
            notification.next_attempt_at = retry_at
        else:
            notification.status = "failed"
        self.session.flush()
        return attempt

    def retry(self, notification_id: int) -> AlarmNotification:
        """Queue a failed notification again (an operator's request)."""
        row = self.get(notification_id)
        if row.status == "delivered":
            raise Conflict(f"notification {notification_id} was delivered")
        row.status = "pending"
        row.next_attempt_at = utcnow()
        self.session.flush()
        return row


def install(factory: Any) -> None:
    """Queue notifications in every session of ``factory`` (a ``sessionmaker``) and deliver
    them after each commit that queued some (:func:`storage.outbox_delivery.kick`)."""
    sa.event.listen(factory, "before_flush", queue_alarm_notifications)
    sa.event.listen(factory, "after_commit", _after_commit)
    sa.event.listen(factory, "after_rollback", _after_rollback)


def _after_commit(session: Session) -> None:
    if session.info.pop(QUEUED_FLAG, False):
        from storage.outbox_delivery import kick  # here: outbox_delivery imports this module

        bind = session.get_bind()
        engine = bind if isinstance(bind, sa.Engine) else bind.engine
        kick(engine)


def _after_rollback(session: Session) -> None:
    session.info.pop(QUEUED_FLAG, None)
