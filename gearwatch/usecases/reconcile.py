"""Physics reconciliation of a record with the simulator: of a file (:func:`reconcile_file`,
``gearwatch reconcile``) or of a stored record (issue 6 over REST): request, then job.

:func:`create_reconciliation` checks a request against what is stored (record, reference, rig,
campaign manifest, model, mechanism names) and adds a ``queued`` row; it never commits.
:func:`run_reconciliation` is the job (run by the service in the background or by the
Dramatiq actor :func:`gearwatch.worker.reconcile_record`): it reads the record's kept raw file
with its campaign's manifest settings, runs :func:`physics.reconcile.reconcile` and stores the
JSON, the HTML report and the updated configuration. It commits twice — ``running`` before the
computation (which can take minutes and must not hold a write transaction) and the outcome
after. Bad input (an unreadable file, no tach pulses, a record too short for a hunting period)
ends as ``failed`` with its reason; the row is never lost.

The physics (``physics.config``, ``physics.simulator``, ``physics.reconcile``) is imported inside
the functions that use it: it loads scipy and the simulator (0.7–1.2 s on a 2-core machine), and
the service imports this module at start-up for its routes, most of which never reconcile.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from sqlalchemy.orm import Session, sessionmaker

from dsp.tach import TachometerError, pulse_times_from_waveform
from gearwatch.floor.defaults import MIN_SAMPLES_PER_MESH, RECONCILE_MAX_FINDINGS, SAMPLES_PER_MESH
from gearwatch.floor.errors import InputError, NotFound
from gearwatch.floor.version import code_version
from gearwatch.usecases.ingest_file import campaign_config, record_suffix
from ingest.sources import read_record
from storage.db import session_scope
from storage.raw_store import RawStore
from storage.repositories import (
    CampaignRepository,
    ReconciliationRepository,
    RecordRepository,
    RigRepository,
)

if TYPE_CHECKING:
    from gearwatch.floor.campaign import Campaign as CampaignConfig
    from gearwatch.floor.campaign import RecordData
    from physics.config import GearPairModel
    from physics.reconcile import MeasuredRecord, ReconciliationResult
    from storage.models import Reconciliation, Record

logger = logging.getLogger(__name__)


@dataclasses.dataclass(frozen=True)
class ReconcileRequest:
    """What a caller asks for (the REST body, the job's options)."""
    model_toml: str | None = None
    reference_record_id: int | None = None
    channel: str | None = None
    mechanisms: tuple[str, ...] | None = None
    """Catalogue names to try; None: every fitted plug-in."""
    samples_per_mesh: int = SAMPLES_PER_MESH
    max_frequency_hz: float | None = None
    max_findings: int = RECONCILE_MAX_FINDINGS
    forward_oversampling: int | None = None
    """Integrator steps per sample of the fitting simulations (None: the model's)."""
    def options(self) -> dict[str, Any]:
        """The stored ``options`` (everything but the model and the reference)."""
        return {
            "samples_per_mesh": self.samples_per_mesh,
            "max_frequency_hz": self.max_frequency_hz,
            "max_findings": self.max_findings,
            "mechanisms": None if self.mechanisms is None else list(self.mechanisms),
            "channel": self.channel,
            "forward_oversampling": self.forward_oversampling,
        }


def parse_model(text: str, pinion_teeth: int, gear_teeth: int) -> GearPairModel:
    """A simulator configuration from TOML text, checked against the rig's tooth counts."""
    from physics.config import model_from_toml
    from physics.simulator import model_geometry

    try:
        model = model_from_toml(text)
        model_geometry(model)
    except (ValueError, TypeError) as error:  # ModelConfigError, GeometryError, bad types
        raise InputError(f"model_toml: {' '.join(str(error).split())}") from None
    g = model.geometry
    if (g.pinion_teeth, g.gear_teeth) != (pinion_teeth, gear_teeth):
        raise InputError(
            f"model_toml: tooth counts {g.pinion_teeth}/{g.gear_teeth} differ from the rig's "
            f"{pinion_teeth}/{gear_teeth}"
        )
    return model


def check_mechanisms(names: tuple[str, ...] | None) -> tuple[str, ...]:
    """The catalogue names to try (the default scan when ``names`` is None)."""
    from physics.reconcile import CATALOGUE, DEFAULT_MECHANISMS

    if names is None:
        return DEFAULT_MECHANISMS
    if not names:
        raise InputError(f"mechanisms: give at least one of {', '.join(CATALOGUE)} (or null)")
    unknown = [m for m in names if m not in CATALOGUE]
    if unknown:
        raise InputError(
            f"mechanisms: unknown or not fitted: {', '.join(unknown)} "
            f"(fitted: {', '.join(CATALOGUE)})"
        )
    return tuple(dict.fromkeys(names))


def check_numbers(request: ReconcileRequest) -> None:
    """The numeric options a reconciliation can use (the mechanisms: :func:`check_mechanisms`)."""
    if request.samples_per_mesh < MIN_SAMPLES_PER_MESH:
        raise InputError(f"samples_per_mesh must be at least {MIN_SAMPLES_PER_MESH}")
    if request.forward_oversampling is not None and request.forward_oversampling < 1:
        raise InputError("forward_oversampling must be at least 1")


def _campaign_of(session: Session, record: Record) -> CampaignConfig:
    return campaign_config(CampaignRepository(session).get(record.campaign_id))


def _channel_of(campaign: CampaignConfig, channel: str | None, what: str) -> str:
    """The accelerometer channel to reconcile; the manifest must allow a reconciliation."""
    tach = campaign.tachometer
    if tach is None:
        raise InputError(f"{what}: its campaign has no tachometer (a pinion reference is needed)")
    if tach.shaft != "pinion":
        raise InputError(
            f"{what}: its campaign's tachometer is on the {tach.shaft} shaft; reconciliation "
            "needs it on the pinion (hunting-period frame)"
        )
    accelerometers = [c.name for c in campaign.accelerometer_channels]
    if not accelerometers:
        raise InputError(f"{what}: its campaign declares no accelerometer channel")
    name = channel or accelerometers[0]
    if name not in accelerometers:
        raise InputError(
            f"channel {name!r} is not an accelerometer channel of {what}'s campaign "
            f"({', '.join(accelerometers)})"
        )
    return name


def raw_path(record: Record, raw_store: RawStore | str | Path | None) -> Path:
    """Where the record's kept raw file is: its stored location, else the same content in
    ``raw_store`` (a worker may mount the shared store elsewhere)."""
    location = Path(record.raw_location)
    if location.is_file():
        return location
    if raw_store is not None:
        store = raw_store if isinstance(raw_store, RawStore) else RawStore(raw_store)
        candidate = store.path_for(record.sha256, record_suffix(location))
        if candidate.is_file():
            return candidate
    raise NotFound(f"raw file of record {record.id} is missing: {record.file_name}")


def create_reconciliation(
    session: Session,
    record_id: int,
    request: ReconcileRequest,
    *,
    raw_store: RawStore | str | Path | None = None,
) -> Reconciliation:
    """Check ``request`` and add a queued :class:`storage.models.Reconciliation` (no commit).

    Raises :class:`NotFound` for an unknown record or reference (or a missing raw file) and
    :class:`InputError` for anything the reconciliation could not use: a reference of another
    rig or the record itself, a model that does not parse or has other tooth counts than the
    rig, unknown mechanisms, a rig without tooth counts, a campaign without a pinion tachometer
    or an unknown channel.
    """
    records = RecordRepository(session)
    record = records.get(record_id)
    reference = None
    if request.reference_record_id is not None:
        if request.reference_record_id == record.id:
            raise InputError("reference_record_id: the reference must be another record")
        try:
            reference = records.get(request.reference_record_id)
        except NotFound:
            raise NotFound(
                f"reference record {request.reference_record_id} not found"
            ) from None
        if reference.rig_id != record.rig_id:
            raise InputError(
                f"reference_record_id: record {reference.id} is of another rig than record "
                f"{record.id}"
            )
    rig = RigRepository(session).get(record.rig_id)
    if not (rig.pinion_teeth and rig.gear_teeth):
        raise InputError(
            f"rig {rig.name!r} has no tooth counts (rig.pinion_teeth, rig.gear_teeth in its "
            "manifest): reconciliation needs them"
        )
    channel = _channel_of(_campaign_of(session, record), request.channel, f"record {record.id}")
    if reference is not None:
        _channel_of(_campaign_of(session, reference), channel, f"record {reference.id}")
    if request.model_toml is not None:
        parse_model(request.model_toml, rig.pinion_teeth, rig.gear_teeth)
    mechanisms = check_mechanisms(request.mechanisms)
    check_numbers(request)
    for stored in (record, reference):
        if stored is not None:
            raw_path(stored, raw_store)
    chosen = dataclasses.replace(
        request,
        channel=channel,
        mechanisms=None if request.mechanisms is None else mechanisms,
    )
    return ReconciliationRepository(session).add(
        record,
        options=chosen.options(),
        code_version=code_version(),
        model_toml=request.model_toml,
        reference=reference,
    )


@dataclasses.dataclass(frozen=True)
class _Inputs:
    """What the computation needs, read in the job's first transaction."""
    record_path: Path
    record_name: str
    campaign: Any
    """The record's campaign (:class:`CampaignConfig`); its rig was checked for tooth counts."""
    reference_path: Path | None
    reference_name: str
    reference_campaign: Any
    request: ReconcileRequest
    title: str


def run_reconciliation(
    session_factory: sessionmaker[Session], raw_store: RawStore | str | Path | None, reconciliation_id: int
) -> str:
    """Run the queued reconciliation ``reconciliation_id``; returns its final status.

    ``raw_store`` (a :class:`storage.raw_store.RawStore` or its root) is where the kept raw
    files are looked up when their stored location is not readable here. A reconciliation that
    already finished is left alone (a message delivered twice).
    """
    with session_scope(session_factory) as session:
        rows = ReconciliationRepository(session)
        row = rows.get(reconciliation_id)
        if not rows.start(row, code_version()):
            return row.status
        try:
            inputs = _inputs(session, row, raw_store)
        except (InputError, NotFound) as error:
            rows.fail(row, _one_line(error))
            return "failed"

    model_toml: str | None = None
    try:
        model_toml, outcome = _compute(inputs, _progress_writer(session_factory, reconciliation_id))
    except (InputError, NotFound, ValueError) as error:
        reason = _one_line(error)
        for path, name in ((inputs.record_path, inputs.record_name),
                           (inputs.reference_path, inputs.reference_name)):
            if path is not None:
                reason = reason.replace(str(path), name)
        outcome = None
    except Exception as error:  # a bug: keep the row and say so, with the traceback in the log
        logger.exception("internal error in reconciliation %s", reconciliation_id)
        reason = f"internal error: {type(error).__name__}: {_one_line(error)}"
        outcome = None

    with session_scope(session_factory) as session:
        rows = ReconciliationRepository(session)
        row = rows.get(reconciliation_id)
        if outcome is None:
            rows.fail(row, reason, model_toml=model_toml)
        else:
            result, report_html, updated = outcome
            assert model_toml is not None
            rows.finish(row, model_toml=model_toml, result=result, report_html=report_html,
                        updated_model_toml=updated)
        return row.status


def _inputs(session: Session, row: Reconciliation, raw_store: RawStore | str | Path | None) -> _Inputs:
    records = RecordRepository(session)
    record = records.get(row.record_id)
    options = dict(row.options or {})
    mechanisms = options.get("mechanisms")
    request = ReconcileRequest(
        model_toml=row.model_toml,
        reference_record_id=row.reference_record_id,
        channel=options.get("channel"),
        mechanisms=None if mechanisms is None else tuple(mechanisms),
        samples_per_mesh=int(options.get("samples_per_mesh", SAMPLES_PER_MESH)),
        max_frequency_hz=options.get("max_frequency_hz"),
        max_findings=int(options.get("max_findings", RECONCILE_MAX_FINDINGS)),
        forward_oversampling=options.get("forward_oversampling"),
    )
    reference = None if row.reference_record_id is None else records.get(row.reference_record_id)
    return _Inputs(
        record_path=raw_path(record, raw_store),
        record_name=record.file_name,
        campaign=_campaign_of(session, record),
        reference_path=None if reference is None else raw_path(reference, raw_store),
        reference_name="" if reference is None else reference.file_name,
        reference_campaign=None if reference is None else _campaign_of(session, reference),
        request=request,
        title=f"reconciliation {row.id}: record {record.id} ({record.file_name})",
    )


PROGRESS_INTERVAL_S = 2.0
"""A running reconciliation's stage and fraction are stored at most this often (and at each
new stage), in its ``result`` column under ``progress`` until the result replaces it."""


def _progress_writer(session_factory: sessionmaker[Session], reconciliation_id: int) -> Any:
    """A :mod:`physics.reconcile.progress` callback that stores the progress on the row."""
    last_at = [0.0]
    last_stage = [""]

    def write(stage: str, fraction: float) -> None:
        now = time.monotonic()
        if stage == last_stage[0] and now - last_at[0] < PROGRESS_INTERVAL_S:
            return
        last_at[0], last_stage[0] = now, stage
        try:
            with session_scope(session_factory) as session:
                ReconciliationRepository(session).set_progress(reconciliation_id, stage, fraction)
        except Exception:  # progress is for people waiting: never fail the job over it
            logger.warning("could not store the progress of reconciliation %s", reconciliation_id,
                           exc_info=True)

    return write


def _compute(inputs: _Inputs, progress: Any = None) -> tuple[str, tuple[dict[str, Any], str, str]]:
    """Read, reconcile, render. Returns the model TOML used and (JSON, HTML, updated TOML);
    raises InputError/ValueError for input the reconciliation cannot use."""
    from physics.config import model_to_toml
    from physics.reconcile import ReconcileOptions, reconcile
    from physics.reconcile.report import html_report

    request = inputs.request
    campaign = inputs.campaign
    measured = measured_from_record(
        read_record(inputs.record_path, campaign), campaign, request.channel, inputs.record_name
    )
    reference = None
    if inputs.reference_path is not None:
        reference = measured_from_record(
            read_record(inputs.reference_path, inputs.reference_campaign),
            inputs.reference_campaign, request.channel, inputs.reference_name,
        )
    rig = campaign.rig
    if request.model_toml is not None:
        model = parse_model(request.model_toml, rig.pinion_teeth, rig.gear_teeth)
        model_toml = request.model_toml
    else:
        model = default_model(campaign, measured.sample_rate_hz)
        model_toml = model_to_toml(model)
    options = ReconcileOptions(
        samples_per_mesh=request.samples_per_mesh,
        max_frequency_hz=request.max_frequency_hz,
        mechanisms=check_mechanisms(request.mechanisms),
        max_findings=request.max_findings,
        forward_oversampling=request.forward_oversampling,
    )
    try:
        result = reconcile(measured, model, reference=reference, options=options, progress=progress)
    except ValueError as error:
        raise InputError(f"{inputs.record_name}: {_one_line(error)}") from None
    return model_toml, (
        result.to_json(),
        html_report(result, title=inputs.title),
        model_to_toml(result.updated_model),
    )


def _one_line(error: BaseException) -> str:
    return " ".join(str(error).split()) or type(error).__name__


def default_model(campaign: CampaignConfig, sample_rate_hz: float) -> GearPairModel:
    """The simulator defaults with the manifest rig's tooth counts, tooth-1 angle and sample rate."""
    from physics.config import GearPairModel

    model = GearPairModel()
    rig = campaign.rig
    if rig.pinion_teeth is None or rig.gear_teeth is None:  # the callers refuse such rigs first
        raise InputError(f"rig {rig.id!r} has no tooth counts: no simulator model to start from")
    geometry = dataclasses.replace(
        model.geometry, pinion_teeth=rig.pinion_teeth, gear_teeth=rig.gear_teeth
    )
    tach = dataclasses.replace(model.tachometer, tooth1_pitch_angle_deg=rig.tooth1_pitch_angle_deg)
    acquisition = dataclasses.replace(model.acquisition, sample_rate_hz=sample_rate_hz)
    return model.replace(geometry=geometry, tachometer=tach, acquisition=acquisition)


def measured_record(path: str | Path, campaign: CampaignConfig, channel: str | None) -> MeasuredRecord:
    """Read a record and return a :class:`MeasuredRecord` of one accelerometer channel."""
    record_path = Path(path)
    if not record_path.is_file():
        raise InputError(f"{record_path}: no such record file")
    return measured_from_record(read_record(record_path, campaign), campaign, channel, str(record_path))


def measured_from_record(
    record: RecordData, campaign: CampaignConfig, channel: str | None, source: str
) -> MeasuredRecord:
    """The :class:`MeasuredRecord` of one accelerometer channel of an already-read record
    (:class:`gearwatch.floor.campaign.RecordData`); ``source`` names the record in error messages."""
    from physics.reconcile import MeasuredRecord

    tach = campaign.tachometer
    if tach is None:
        raise InputError("the manifest has no [tachometer]: reconciliation needs a pinion reference")
    if tach.shaft != "pinion":
        raise InputError("reconcile needs the tachometer on the pinion shaft (hunting-period frame)")
    accelerometers = [c.name for c in campaign.accelerometer_channels]
    if not accelerometers:
        raise InputError("the manifest declares no accelerometer channel")
    name = channel or accelerometers[0]
    if name not in accelerometers:
        raise InputError(f"--channel {name!r} is not an accelerometer channel of the manifest")
    fs = float(record.sample_rate_hz)
    raw = np.asarray(record.channel(tach.channel), dtype=np.float64)
    try:
        pulses = pulse_times_from_waveform(raw, fs, edge=tach.edge) if tach.kind == "pulses" else raw
    except (TachometerError, ValueError) as error:
        raise InputError(f"{source}: tachometer: {error}") from None
    signal = np.asarray(record.channel(name), dtype=np.float64)
    return MeasuredRecord(signal, fs, np.asarray(pulses, dtype=np.float64), tach.pulses_per_rev)


def reconcile_file(
    record: str | Path,
    campaign: CampaignConfig,
    request: ReconcileRequest,
    *,
    model: GearPairModel | None = None,
    model_name: str = "model",
    reference: str | Path | None = None,
    progress: Any = None,
) -> ReconciliationResult:
    """Reconcile a record file described by ``campaign`` (``gearwatch reconcile``).

    ``model`` is the simulator configuration (None: :func:`default_model` of the manifest rig);
    ``model_name`` names it in messages; ``reference`` is a healthy record file of the same rig.
    ``request.model_toml`` and ``request.reference_record_id`` are for stored records and ignored.
    Returns the :class:`physics.reconcile.ReconciliationResult`; bad input is an InputError.
    """
    from physics.reconcile import ReconcileOptions, reconcile

    if not (campaign.rig.pinion_teeth and campaign.rig.gear_teeth):
        raise InputError("reconcile needs rig.pinion_teeth and rig.gear_teeth in the manifest")
    measured = measured_record(record, campaign, request.channel)
    reference_record = (
        measured_record(reference, campaign, request.channel) if reference else None
    )
    if model is not None:
        g = model.geometry
        if (g.pinion_teeth, g.gear_teeth) != (campaign.rig.pinion_teeth, campaign.rig.gear_teeth):
            raise InputError(f"{model_name}: tooth counts differ from the manifest's rig")
    else:
        model = default_model(campaign, measured.sample_rate_hz)
    mechanisms = check_mechanisms(request.mechanisms)
    check_numbers(request)
    options = ReconcileOptions(
        samples_per_mesh=request.samples_per_mesh,
        max_frequency_hz=request.max_frequency_hz,
        mechanisms=mechanisms,
        max_findings=request.max_findings,
        forward_oversampling=request.forward_oversampling,
    )
    try:
        return reconcile(measured, model, reference=reference_record, options=options, progress=progress)
    except ValueError as error:
        raise InputError(f"{record}: {error}") from None
