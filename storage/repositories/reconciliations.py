"""Physics reconciliations of stored records."""

from __future__ import annotations

import builtins
from typing import Any

import sqlalchemy as sa

from storage.models import (
    Reconciliation,
    Record,
    utcnow,
)
from storage.repositories.base import Repository, json_safe


class ReconciliationRepository(Repository[Reconciliation]):
    """Physics reconciliations of stored records: queued → running → done | failed."""

    model = Reconciliation
    noun = "reconciliation"

    def add(
        self,
        record: Record,
        *,
        options: dict[str, Any],
        code_version: str,
        model_toml: str | None = None,
        reference: Record | None = None,
    ) -> Reconciliation:
        """A queued reconciliation of ``record`` (``model_toml`` None: the rig's default model)."""
        row = Reconciliation(
            record_id=record.id,
            reference_record_id=None if reference is None else reference.id,
            status="queued",
            options=json_safe(options),
            model_toml=model_toml,
            code_version=code_version,
            created_at=utcnow(),
        )
        self.session.add(row)
        self.session.flush()
        return row

    def list_for_record(self, record_id: int) -> builtins.list[Reconciliation]:
        """Newest first."""
        query = (
            sa.select(Reconciliation)
            .where(Reconciliation.record_id == record_id)
            .order_by(Reconciliation.created_at.desc(), Reconciliation.id.desc())
        )
        return list(self.session.scalars(query))

    def start(self, row: Reconciliation, code_version: str) -> bool:
        """Mark ``row`` running with the code that runs it; False when it already finished
        (a message delivered twice). A ``running`` row is started again: its worker died."""
        if row.status in ("done", "failed"):
            return False
        row.status = "running"
        row.code_version = code_version
        row.started_at = utcnow()
        row.error = ""
        self.session.flush()
        return True

    def set_progress(self, reconciliation_id: int, stage: str, fraction: float) -> None:
        """Store a running reconciliation's stage and fraction done (``result.progress``; the
        result replaces it when done)."""
        row = self.get(reconciliation_id)
        if row.status != "running":
            return
        row.result = {"progress": {"stage": stage, "fraction": round(float(fraction), 4)}}
        self.session.flush()

    def finish(
        self,
        row: Reconciliation,
        *,
        model_toml: str,
        result: dict[str, Any],
        report_html: str,
        updated_model_toml: str,
    ) -> Reconciliation:
        row.status = "done"
        row.model_toml = model_toml
        row.result = json_safe(result)
        row.report_html = report_html
        row.updated_model_toml = updated_model_toml
        row.error = ""
        row.finished_at = utcnow()
        self.session.flush()
        return row

    def fail(self, row: Reconciliation, reason: str, *, model_toml: str | None = None) -> Reconciliation:
        row.status = "failed"
        row.error = reason or "failed"
        if model_toml is not None:
            row.model_toml = model_toml
        row.finished_at = utcnow()
        self.session.flush()
        return row
