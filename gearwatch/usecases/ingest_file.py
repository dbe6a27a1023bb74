"""The per-record job: keep the raw file → read → pipeline → store results → evaluate alarms.

One function, :func:`process_file`, serves ``gearwatch replay``, ``gearwatch watch``, the
service's uploads and the Dramatiq actor (:mod:`gearwatch.worker`). It works inside a session
it is given and never commits; the caller commits once per record, so a record's row, results
and alarm changes appear together or not at all.

Idempotency (on the raw file's sha256, per campaign):

* the same file again with the same parameters changes nothing (outcome ``unchanged``);
* the same file with new parameters adds a result version and keeps the old ones
  (``reprocessed``); alarms are evaluated once per record, on its first accepted result;
* a record rejected for bad input (unreadable file, failed quality check) is stored with
  status ``rejected`` and the reason, and never raises alarms. It is tried again only with
  other parameters (a looser quality limit may accept it) or when the failure was an internal
  error rather than bad input.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import functools
import inspect
import logging
import os
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from sqlalchemy.exc import SQLAlchemyError
from sqlalchemy.orm import Session

from gearwatch.floor.campaign import Campaign as CampaignConfig
from gearwatch.floor.campaign import (
    ChannelConfig,
    RecordData,
    RecordEntry,
    RigConfig,
    TachometerConfig,
)
from gearwatch.floor.errors import InputError, NotFound
from gearwatch.floor.results import AnalysisParameters, RecordAnalysis
from gearwatch.usecases import running_baselines
from gearwatch.usecases.alarms import evaluate_record
from gearwatch.usecases.analyze import Baselines, analyze_record
from gearwatch.usecases.tachless import fold_reference
from gearwatch.usecases.tooth_change import refresh_tooth_change
from ingest.sources import file_sha256, read_record, registered_suffixes
from storage.repositories import (
    AlarmRuleRepository,
    CampaignRepository,
    RecordRepository,
    RigRepository,
    json_safe,
)
from storage.tooth_frames import ToothFrameRepository

if TYPE_CHECKING:
    from storage.models import Campaign as StoredCampaign
    from storage.models import Record

logger = logging.getLogger(__name__)

Outcome = Literal["accepted", "rejected", "unchanged", "reprocessed"]

Analyzer = Callable[
    [RecordData, CampaignConfig, AnalysisParameters, str, dict[str, dict[str, float]]],
    RecordAnalysis,
]
"""``(record, campaign, params, input_sha256, baseline_stats) -> RecordAnalysis``, where
``baseline_stats`` maps each accelerometer channel to the mean ``baseline_stats`` of earlier
records; the default (:func:`pipeline_analyzer`) runs :func:`gearwatch.usecases.analyze.analyze_record`.
Tests pass their own."""


@dataclasses.dataclass(frozen=True)
class JobResult:
    record_id: int
    sha256: str
    outcome: Outcome
    status: str
    """The record's status afterwards: ``accepted`` or ``rejected``."""
    reason: str = ""
    result_id: int | None = None
    alarm_changes: tuple[Any, ...] = ()
    """:class:`gearwatch.usecases.alarms.AlarmChange` items caused by this record."""


def pipeline_analyzer(
    record: RecordData,
    campaign: CampaignConfig,
    params: AnalysisParameters,
    input_sha256: str,
    baselines: dict[str, dict[str, float]],
    tooth_frames: dict[str, Any] | None = None,
) -> RecordAnalysis:
    running = {
        channel: Baselines(
            na4_residual_variance=stats.get("residual_variance"),
            nb4_envelope_variance=stats.get("envelope_variance"),
        )
        for channel, stats in baselines.items()
    }
    return analyze_record(record, campaign, params, input_sha256=input_sha256, baselines=running,
                          tooth_frames=tooth_frames)


def _tooth_frame_arguments(session: Session, campaign_id: int, analyze: Analyzer) -> dict[str, Any]:
    """``tooth_frames=`` (the campaign's references, :mod:`storage.tooth_frames`) for an analyzer
    that takes it: tach-less records are then numbered in the campaign's tooth frame."""
    try:
        accepts = "tooth_frames" in inspect.signature(analyze).parameters
    except (TypeError, ValueError):  # pragma: no cover - builtins without a signature
        accepts = False
    if not accepts:
        return {}
    return {"tooth_frames": ToothFrameRepository(session).references(campaign_id)}


def parse_taken_at(text: str) -> dt.datetime:
    """An ISO 8601 timestamp with time zone (``Z`` allowed) as an aware UTC datetime."""
    try:
        value = dt.datetime.fromisoformat(text.strip().replace("Z", "+00:00"))
    except ValueError:
        raise InputError(f"invalid timestamp {text!r} (ISO 8601 with time zone expected)") from None
    if value.tzinfo is None:
        raise InputError(f"timestamp {text!r} has no time zone")
    return value.astimezone(dt.UTC)


def record_suffix(path: str | Path) -> str:
    """The suffix the readers know the file by (``.csv.gz`` rather than ``.gz``)."""
    name = Path(path).name.lower()
    matches = [s for s in registered_suffixes() if name.endswith(s)]
    if matches:
        return max(matches, key=len)
    return Path(path).suffix.lower()


def campaign_config(campaign: StoredCampaign) -> CampaignConfig:
    """Rebuild the manifest settings of a stored campaign (:class:`storage.models.Campaign`)."""
    data = campaign.manifest or {}
    rig = data.get("rig") or {"id": campaign.rig.name}
    tach = data.get("tachometer")
    return CampaignConfig(
        id=campaign.name,
        description=campaign.description,
        rig=RigConfig(**rig),
        sample_rate_hz=data.get("sample_rate_hz"),
        tachometer=TachometerConfig(**tach) if tach else None,
        channels=tuple(ChannelConfig(**c) for c in data.get("channels", ())),
        root=Path(data.get("root", ".")),
    )


def _expected_parameters(params: AnalysisParameters, campaign: CampaignConfig) -> dict[str, Any]:
    expected: dict[str, Any] = dict(params.to_dict())
    expected.update(
        pinion_teeth=campaign.rig.pinion_teeth,
        gear_teeth=campaign.rig.gear_teeth,
        tooth1_pitch_angle_deg=campaign.rig.tooth1_pitch_angle_deg,
    )
    if campaign.tachometer is not None:
        tach = campaign.tachometer
        expected["tachometer"] = {
            "kind": tach.kind, "shaft": tach.shaft, "pulses_per_rev": tach.pulses_per_rev
        }
    return expected


def _same_parameters(stored: dict[str, Any], expected: dict[str, Any]) -> bool:
    """Stored result parameters match on every key both sides know."""
    expected = json_safe(expected)
    return all(stored[key] == value for key, value in expected.items() if key in stored)


def _baseline_stats(
    session: Session, campaign_id: int, campaign: CampaignConfig, before: dt.datetime
) -> dict[str, dict[str, float]]:
    """Per accelerometer channel, the mean ``baseline_stats`` of the campaign's earlier
    accepted records (empty when there are none: NA4/NB4 then use the record's own variance)."""
    records = RecordRepository(session)
    return {
        channel.name: records.mean_baseline_stats(campaign_id, channel.name, before=before)
        for channel in campaign.accelerometer_channels
    }


def process_file(
    session: Session,
    path: str | Path,
    campaign: CampaignConfig,
    *,
    raw_store: Any,
    params: AnalysisParameters | None = None,
    taken_at: dt.datetime | str | None = None,
    label: str = "",
    file_name: str | None = None,
    analyzer: Analyzer | None = None,
) -> JobResult:
    """Ingest one record file of ``campaign`` (see the module docstring).

    ``raw_store`` is a :class:`storage.raw_store.RawStore`. ``taken_at`` defaults to the
    manifest's entry for this file, else the reader's ``taken_at`` metadata, else the file's
    modification time. Bad input never raises: the record is stored as rejected. Internal
    errors (bugs) are stored as rejected too, logged with their traceback and retried on the
    next ingestion.
    """
    path = Path(path)
    params = params or AnalysisParameters()
    analyze = analyzer or pipeline_analyzer
    if not path.is_file():
        raise InputError(f"{path}: no such record file")
    sha256 = file_sha256(path)

    campaigns = CampaignRepository(session)
    is_new_rig = False
    stored_campaign = campaigns.get_by_name(campaign.id)
    if stored_campaign is None:
        is_new_rig = RigRepository(session).get_by_name(campaign.rig.id) is None
    stored_campaign = campaigns.ensure(campaign)
    if is_new_rig:
        AlarmRuleRepository(session).ensure_defaults(stored_campaign.rig_id)

    records = RecordRepository(session)
    record = records.get_by_sha256(stored_campaign.id, sha256)
    expected = _expected_parameters(params, campaign)
    if record is not None:
        if record.status == "accepted":
            if any(_same_parameters(r.parameters, expected) for r in records.results(record.id)):
                return JobResult(record.id, sha256, "unchanged", record.status,
                                 result_id=_current_id(records, record.id))
        elif record.status == "rejected" and not (record.quality or {}).get("internal_error"):
            rejected_with = (record.quality or {}).get("rejected_parameters")
            if rejected_with is not None and _same_parameters(rejected_with, expected):
                return JobResult(record.id, sha256, "unchanged", record.status, record.reason)
        attempt = _analyze(session, Path(record.raw_location), sha256, record.taken_at,
                           campaign, params, analyze, stored_campaign.id,
                           display_name=record.file_name)
        return _store(session, record, attempt, campaign, params)

    if taken_at is None:
        taken_at = _taken_at_from_manifest(path, campaign)
    if isinstance(taken_at, str):
        taken_at = parse_taken_at(taken_at)
    kept = raw_store.keep(path, sha256, record_suffix(path))
    provisional = taken_at or dt.datetime.fromtimestamp(path.stat().st_mtime, dt.UTC)
    # Analyse first, write after: the write transaction (a database-wide lock on SQLite)
    # stays short and never spans the signal processing.
    attempt = _analyze(session, kept, sha256, provisional, campaign, params, analyze,
                       stored_campaign.id, time_from_metadata=taken_at is None,
                       display_name=file_name or path.name)
    record = records.add(
        stored_campaign,
        sha256=sha256,
        file_name=file_name or path.name,
        raw_location=str(kept),
        taken_at=attempt.taken_at,
        size_bytes=path.stat().st_size,
        label=label or _label_from_manifest(path, campaign),
    )
    return _store(session, record, attempt, campaign, params)


def _current_id(records: RecordRepository, record_id: int) -> int | None:
    current = records.current_result(record_id)
    return None if current is None else int(current.id)


@functools.lru_cache(maxsize=8)
def _manifest_index(campaign: CampaignConfig) -> dict[Path, RecordEntry]:
    """Resolved record path → manifest entry (a replay looks up every record of a campaign)."""
    return {campaign.record_path(entry).resolve(): entry for entry in campaign.records}


def _manifest_entry(path: Path, campaign: CampaignConfig) -> RecordEntry | None:
    try:
        index = _manifest_index(campaign)
    except TypeError:  # an unhashable campaign (never from the manifest loader)
        index = {campaign.record_path(e).resolve(): e for e in campaign.records}
    return index.get(path.resolve())


def _taken_at_from_manifest(path: Path, campaign: CampaignConfig) -> dt.datetime | None:
    entry = _manifest_entry(path, campaign)
    return None if entry is None else parse_taken_at(entry.taken_at)


def _label_from_manifest(path: Path, campaign: CampaignConfig) -> str:
    entry = _manifest_entry(path, campaign)
    return "" if entry is None else entry.label


@dataclasses.dataclass
class _Attempt:
    """What reading and analysing one raw file gave: an analysis or the reason it failed."""

    taken_at: dt.datetime
    analysis: RecordAnalysis | None = None
    reason: str = ""
    error: str = ""
    internal: bool = False


def _analyze(
    session: Session,
    raw_location: Path,
    sha256: str,
    taken_at: dt.datetime,
    campaign: CampaignConfig,
    params: AnalysisParameters,
    analyze: Analyzer,
    campaign_id: int,
    *,
    time_from_metadata: bool = False,
    display_name: str | None = None,
) -> _Attempt:
    """Read the kept raw file and run the chain; never raises for bad input or a bug.

    Reasons name the file as the operator knows it (``display_name``), not its content-addressed
    copy in the raw store."""
    attempt = _Attempt(taken_at)
    try:
        data = read_record(raw_location, campaign)
        if time_from_metadata and data.metadata.get("taken_at"):
            attempt.taken_at = parse_taken_at(data.metadata["taken_at"])
        baselines = _baseline_stats(session, campaign_id, campaign, attempt.taken_at)
        attempt.analysis = analyze(data, campaign, params, sha256, baselines,
                                   **_tooth_frame_arguments(session, campaign_id, analyze))
    except InputError as error:
        attempt.reason, attempt.error = _one_line(error), type(error).__name__
    except SQLAlchemyError:
        raise  # the database failed, not the record: nothing is stored, a re-run resumes
    except Exception as error:
        logger.exception("internal error while analysing %s", raw_location)
        attempt.reason = f"internal error: {type(error).__name__}: {_one_line(error)}"
        attempt.error, attempt.internal = type(error).__name__, True
    if display_name and attempt.reason:
        attempt.reason = attempt.reason.replace(str(raw_location), display_name)
    return attempt


def _store(
    session: Session,
    record: Any,
    attempt: _Attempt,
    campaign: CampaignConfig,
    params: AnalysisParameters,
) -> JobResult:
    """Write the outcome of an attempt: rejection, or results (+ alarms on first acceptance)."""
    records = RecordRepository(session)
    analysis = attempt.analysis
    if analysis is None and record.status == "accepted" and records.current_result(record.id):
        # A failed re-analysis (other parameters) must not take an accepted record and its
        # current result out of the trends: the attempt is rejected, the record is not.
        return JobResult(record.id, record.sha256, "rejected", record.status,
                         f"not reprocessed, the current result is kept: {attempt.reason}",
                         result_id=_current_id(records, record.id))
    if analysis is None:
        records.mark_rejected(record, attempt.reason)
        if attempt.internal:
            record.quality = {"internal_error": True, "error": attempt.error}
        else:
            record.quality = {
                "rejected_parameters": json_safe(_expected_parameters(params, campaign)),
                "error": attempt.error,
            }
        session.flush()
        return JobResult(record.id, record.sha256, "rejected", "rejected", record.reason)

    first_acceptance = record.status != "accepted"
    if not first_acceptance and records.result_for_parameters(
        record.id, analysis.provenance.parameters
    ) is not None:
        return JobResult(record.id, record.sha256, "unchanged", record.status,
                         result_id=_current_id(records, record.id))
    records.mark_accepted(record, analysis)
    result = records.add_result(record, analysis)
    # NA4/NB4 of every accepted record follow the campaign's taken_at order, whatever order the
    # records arrived in (before the alarm evaluation, which then sees the rescaled values).
    running_baselines.lock_rig(session, record.rig_id)
    # called through its module: the arrival-order test counts its rescalings there
    running_baselines.refresh_running_baselines(session, record.campaign_id)
    refresh_tooth_change(session, record.campaign_id, record.id)  # the per-tooth change, same rule
    changes: tuple[Any, ...] = ()
    if first_acceptance:  # a record enters its campaign's tooth-frame reference once
        _fold_tooth_frames(session, record, analysis)
        changes = tuple(evaluate_record(session, record, result))
    outcome: Outcome = "accepted" if first_acceptance else "reprocessed"
    return JobResult(record.id, record.sha256, outcome, "accepted", result_id=result.id,
                     alarm_changes=changes)


def _fold_tooth_frames(session: Session, record: Record, analysis: RecordAnalysis) -> None:
    """Found or refine the campaign's tooth-frame references with this accepted record."""
    frames = ToothFrameRepository(session)
    current = frames.references(record.campaign_id)
    for channel in analysis.channels:
        folded = fold_reference(current.get(channel.channel), channel, record.sha256)
        if folded is not None:
            frames.save(record.campaign_id, channel.channel, folded)


def _one_line(error: BaseException) -> str:
    return " ".join(str(error).split()) or type(error).__name__


def reprocess_record(
    session: Session,
    record_id: int,
    params: AnalysisParameters,
    *,
    analyzer: Analyzer | None = None,
) -> JobResult:
    """Analyse a stored record again from its kept raw file with ``params``.

    A new parameter set adds a result version (the old ones are kept); the same parameters
    again change nothing.
    """
    records = RecordRepository(session)
    record = records.get(record_id)
    if not os.path.isfile(record.raw_location):
        raise NotFound(f"raw file of record {record_id} is missing: {record.raw_location}")
    campaign = campaign_config(CampaignRepository(session).get(record.campaign_id))
    expected = _expected_parameters(params, campaign)
    if record.status == "accepted" and any(
        _same_parameters(r.parameters, expected) for r in records.results(record.id)
    ):
        return JobResult(record.id, record.sha256, "unchanged", record.status,
                         result_id=_current_id(records, record.id))
    attempt = _analyze(session, Path(record.raw_location), record.sha256, record.taken_at,
                       campaign, params, analyzer or pipeline_analyzer, record.campaign_id,
                       display_name=record.file_name)
    return _store(session, record, attempt, campaign, params)
