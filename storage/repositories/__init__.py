"""Every database query of gearwatch, grouped by entity.

Repositories take a :class:`~sqlalchemy.orm.Session`, add and query, and ``flush`` — they never
commit. The caller (a request handler, a job, a CLI command) owns the transaction, typically
with :func:`storage.db.session_scope`.

Missing rows raise :class:`gearwatch.floor.errors.NotFound`; a state change that is not allowed
(e.g. acknowledging a cleared alarm) raises :class:`gearwatch.floor.errors.Conflict`.

One module per aggregate over :class:`~storage.repositories.base.Repository`; this package
exports every repository, so callers write ``from storage.repositories import RecordRepository``.
"""

from storage.repositories.alarms import (
    ALARM_INDICATORS,
    RULE_FIELDS,
    AlarmRepository,
    AlarmRuleRepository,
)
from storage.repositories.audit import AuditRepository
from storage.repositories.base import Repository, json_safe, parameters_sha256
from storage.repositories.keys import ApiKeyRepository
from storage.repositories.reconciliations import ReconciliationRepository
from storage.repositories.records import CurveData, RecordRepository
from storage.repositories.rigs import (
    CampaignRepository,
    GearPair,
    RigRepository,
    gear_pair,
    rig_gear_pair,
)
from storage.repositories.trends import TrendMatrix, TrendPoint, TrendRepository

__all__ = [
    "ALARM_INDICATORS",
    "RULE_FIELDS",
    "AlarmRepository",
    "AlarmRuleRepository",
    "ApiKeyRepository",
    "AuditRepository",
    "CampaignRepository",
    "CurveData",
    "GearPair",
    "ReconciliationRepository",
    "RecordRepository",
    "Repository",
    "RigRepository",
    "TrendMatrix",
    "TrendPoint",
    "TrendRepository",
    "gear_pair",
    "json_safe",
    "parameters_sha256",
    "rig_gear_pair",
]
