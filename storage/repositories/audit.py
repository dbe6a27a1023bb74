"""The audit log: who did what, when."""

from __future__ import annotations

import builtins
import datetime as dt
from typing import Any

import sqlalchemy as sa

from storage.models import (
    AuditEntry,
    utcnow,
)
from storage.repositories.base import Repository, json_safe


class AuditRepository(Repository[AuditEntry]):
    model = AuditEntry
    noun = "audit entry"

    def add(
        self, who: str, action: str, target: str = "", details: dict[str, Any] | None = None
    ) -> AuditEntry:
        entry = AuditEntry(
            who=who, action=action, target=target, details=json_safe(details or {}), at=utcnow()
        )
        self.session.add(entry)
        self.session.flush()
        return entry

    def list(
        self,
        *,
        who: str | None = None,
        action: str | None = None,
        since: dt.datetime | None = None,
        limit: int | None = 100,
        offset: int = 0,
    ) -> builtins.list[AuditEntry]:
        """Newest first."""
        query = sa.select(AuditEntry)
        if who is not None:
            query = query.where(AuditEntry.who == who)
        if action is not None:
            query = query.where(AuditEntry.action == action)
        if since is not None:
            query = query.where(AuditEntry.at >= since)
        query = query.order_by(AuditEntry.at.desc(), AuditEntry.id.desc()).offset(offset)
        if limit is not None:
            query = query.limit(limit)
        return list(self.session.scalars(query))
