"""End to end, on SQLite AND PostgreSQL: record files or CAN frames → the per-record job → database.

(a) the simulated 12-day campaign (spall on pinion tooth 16 from day 10), 16-bit PCM WAV, through
    :func:`gearwatch.usecases.replay.replay_campaign`: every record accepted, the stored per-tooth
    ``mci_depth`` trend alarms on tooth 16 and on no other tooth;
(b) the real wind-turbine campaign (MAT, pulse-time tachometer, no tooth counts): 10 records
    accepted, whole-record metrics stored, the kurtosis trend rises;
(c) the same simulated campaign played by the rig emulator onto a python-can bus (``virtual``;
    the last record over ``udp_multicast`` on loopback when that works here), assembled live,
    written as the CAN log ``gearwatch listen-can`` writes, and ingested by the same job
    (:func:`gearwatch.usecases.ingest_file.process_file`) into another database: every stored per-tooth value,
    metric, curve and alarm equals (a)'s exactly, record by record.
"""

from __future__ import annotations

import datetime as dt
import queue
import random
import threading
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import can
import numpy as np
import pytest

from gearwatch.floor.campaign import Campaign, RecordData
from gearwatch.floor.results import HISTORY_TOOTH_INDICATORS, TOOTH_INDICATORS
from gearwatch.usecases.ingest_file import JobResult, parse_taken_at, process_file
from gearwatch.usecases.replay import ReplaySummary, replay_campaign
from ingest.can.assembler import AssembledRecord, RecordAssembler
from ingest.can.emulator import emulate
from ingest.can.live import listen, open_bus
from ingest.manifest import load_manifest
from ingest.sources import read_record
from storage.db import session_scope
from storage.raw_store import RawStore
from storage.repositories import (
    AlarmRepository,
    CampaignRepository,
    RecordRepository,
    RigRepository,
    TrendRepository,
)
from tests.conftest import IN_CI
from tests.ingest.can_flow import random_group, windowed
from tests.integration.conftest import (
    CAMPAIGN_DAYS,
    PCM_FULL_SCALE,
    SPALL_ONSET_DAY,
    SPALL_TOOTH,
    Database,
)

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[2]
WINDTURBINE_EXAMPLE = REPO / "examples" / "windturbine-hss" / "campaign.toml"
WINDTURBINE_DATA = REPO.parent / "shared" / "data" / "real" / "windturbine-hss"
UDP_FRAMES_PER_S = 4_000.0
"""UDP sockets drop datagrams when flooded: the emulator's rate cap is its flow control there."""


# -- what a database holds about a campaign, for exact comparison ---------------------------------
def stored_campaign(database: Database, campaign_name: str) -> list[dict[str, Any]]:
    """Per record (oldest first): the record row and its current result with every per-tooth
    indicator, metric and curve, channels by name; nothing that names the raw file."""
    rows: list[dict[str, Any]] = []
    with session_scope(database.factory) as session:
        stored = CampaignRepository(session).get_by_name(campaign_name)
        assert stored is not None
        names = {c.id: c.name for c in CampaignRepository(session).channels(stored.id)}
        records = RecordRepository(session)
        for record in records.list(campaign_id=stored.id, limit=None):
            row: dict[str, Any] = {
                "taken_at": record.taken_at,
                "label": record.label,
                "status": record.status,
                "reason": record.reason,
                "speed": (record.speed_rpm, record.speed_min_rpm, record.speed_max_rpm,
                          record.speed_variation, record.revolutions),
                "quality": record.quality,
            }
            result = records.current_result(record.id)
            if result is not None:
                row["result"] = {
                    "parameters": result.parameters,
                    "code_version": result.code_version,
                    "summary": (result.speed_rpm, result.revolutions, result.samples_per_rev),
                    "channels": [
                        (names[c.channel_id], c.revolutions, c.gear_revolutions, c.speed_rpm,
                         c.samples_per_rev, c.worst_tooth, c.baseline_stats)
                        for c in records.channel_results(result.id)
                    ],
                    "teeth": [
                        (names[t.channel_id], t.tooth, t.indicator, t.value)
                        for t in records.tooth_indicators(result.id)
                    ],
                    "metrics": [
                        (names[m.channel_id], m.metric, m.value) for m in records.metrics(result.id)
                    ],
                    "curves": [
                        (c.channel, c.name, c.values.dtype.str, c.values.tobytes())
                        for c in records.curves(result.id)
                    ],
                }
            rows.append(row)
    return rows


def stored_alarms(database: Database, rig_name: str) -> list[tuple[Any, ...]]:
    """Every alarm of the rig with its history, oldest first."""
    with session_scope(database.factory) as session:
        rig = RigRepository(session).get_by_name(rig_name)
        assert rig is not None
        alarms = AlarmRepository(session)
        return [
            (a.indicator, a.channel.name, a.tooth, a.state, a.severity, a.raised_at,
             a.last_value, a.last_score, a.baseline_centre, a.baseline_spread,
             [(e.state, e.at) for e in alarms.history(a.id)])
            for a in reversed(alarms.list(rig_id=rig.id, limit=None))
        ]


# -- (a) the simulated campaign from its files ------------------------------------------------
Replay = tuple[Database, ReplaySummary, RawStore]


@pytest.fixture(scope="session")
def file_replay(
    pcm_campaign: Path, fresh_database: Callable[[], Database],
    tmp_path_factory: pytest.TempPathFactory,
) -> Replay:
    database = fresh_database()
    store = RawStore(tmp_path_factory.mktemp("raw-files"))
    summary = replay_campaign(pcm_campaign, database.factory, store, progress=False)
    return database, summary, store


def test_simulated_campaign_files_are_accepted_and_alarm_on_the_spalled_tooth_only(
    file_replay: Replay, pcm_campaign: Path
) -> None:
    database, summary, store = file_replay
    campaign = load_manifest(pcm_campaign)
    assert summary.outcomes == {"accepted": CAMPAIGN_DAYS}, summary.rejected
    assert summary.internal_errors == 0

    alarms = stored_alarms(database, campaign.rig.id)
    # The former mci_depth rule: one alarm, on the spalled tooth, at alarm level and still open.
    # The score rule: on the spalled tooth, and at most on a neighbour too (one spall's well
    # spills into the sectors beside it: a known limit, benchmarks/bench_detection.py).
    # (Whole-record alarms, tooth 0, come too: FM4 and kurtosis see the spall as well.)
    per_tooth = [(a[0], a[2], a[3], a[4]) for a in alarms if a[2] != 0]
    assert [p for p in per_tooth if p[0] == "mci_depth"] == [
        ("mci_depth", SPALL_TOOTH, "alarm", "alarm")
    ], alarms
    score_teeth = {p[1] for p in per_tooth if p[0] == "score"}
    assert SPALL_TOOTH in score_teeth, alarms
    assert score_teeth <= {SPALL_TOOTH - 1, SPALL_TOOTH, SPALL_TOOTH + 1}, alarms
    onset = parse_taken_at(campaign.records[SPALL_ONSET_DAY - 1].taken_at)
    assert all(a[5] >= onset for a in alarms), "an alarm before the spall"

    with session_scope(database.factory) as session:
        rig = RigRepository(session).get_by_name(campaign.rig.id)
        assert rig is not None and rig.pinion_teeth == 20
        trend = TrendRepository(session).trend(rig.id, "mci_depth")
    depth = np.array([p.value for p in trend]).reshape(CAMPAIGN_DAYS, 20)  # day × tooth
    assert [p.tooth for p in trend[:20]] == list(range(1, 21))
    healthy, spalled = depth[: SPALL_ONSET_DAY - 1], depth[SPALL_ONSET_DAY - 1 :]
    # The spalled tooth's well deepens beyond anything the healthy days showed; the others don't.
    rise = spalled.max(axis=0) - healthy.max(axis=0)
    assert rise[SPALL_TOOTH - 1] > 0.1 and int(np.argmax(rise)) == SPALL_TOOTH - 1, rise.round(3)

    again = replay_campaign(pcm_campaign, database.factory, store, progress=False)
    assert again.outcomes == {"unchanged": CAMPAIGN_DAYS} and again.alarm_changes == 0


def test_pcm_records_read_as_whole_counts_of_the_full_scale(pcm_campaign: Path) -> None:
    """The fixture's records are what a 16-bit DAQ writes: count / 32768 of the full scale."""
    campaign = load_manifest(pcm_campaign)
    record = read_record(campaign.record_path(campaign.records[-1]), campaign)
    assert record.metadata["dtype"] == "int16"
    for name, samples in record.channels.items():
        counts = samples.astype(np.float64) * 32768
        assert np.array_equal(counts, np.rint(counts)) and np.abs(counts).max() <= 32766
        assert np.ptp(counts) > 1000, name  # the full scale leaves the signal thousands of counts
    assert set(record.channels) == set(PCM_FULL_SCALE)


# -- (b) the real wind-turbine campaign --------------------------------------------------------
@pytest.fixture(scope="session")
def windturbine_replay(
    fresh_database: Callable[[], Database], tmp_path_factory: pytest.TempPathFactory
) -> Replay:
    if not WINDTURBINE_DATA.is_dir():
        if IN_CI:
            pytest.fail(f"{WINDTURBINE_DATA} is missing: CI must provide shared/ beside the repo")
        pytest.skip(f"{WINDTURBINE_DATA} not present")
    database = fresh_database()
    store = RawStore(tmp_path_factory.mktemp("raw-windturbine"))
    summary = replay_campaign(WINDTURBINE_EXAMPLE, database.factory, store, progress=False)
    return database, summary, store


def windturbine_trend(database: Database, metric: str) -> tuple[np.ndarray, np.ndarray]:
    """(days since the first record, stored values) of a whole-record metric."""
    with session_scope(database.factory) as session:
        rig = RigRepository(session).get_by_name("windturbine-hss")
        assert rig is not None and rig.pinion_teeth is None
        points = TrendRepository(session).metric_trend(rig.id, metric)
    days = np.array([(p.taken_at - points[0].taken_at) / dt.timedelta(days=1) for p in points])
    return days, np.array([p.value for p in points])


def raw_vibration_kurtosis() -> np.ndarray:
    """Independent reference: each file's raw vibration cut into ``raw_kurtosis``'s time spans
    (equal parts), the mean of their kurtoses weighted by their sizes, oldest first."""
    import scipy.io
    import scipy.stats

    from gearwatch.usecases.signal_checks import kurtosis_span_edges

    files = sorted(WINDTURBINE_DATA.glob("data-*.mat"))
    out = []
    for f in files:
        x = scipy.io.loadmat(f)["vibration"].ravel()
        spans = np.split(x, kurtosis_span_edges(x.size)[1:-1])
        out.append(np.average([scipy.stats.kurtosis(span, fisher=False) for span in spans],
                              weights=[span.size for span in spans]))
    return np.array(out)


def test_real_wind_turbine_campaign_is_accepted_with_whole_record_metrics(
    windturbine_replay: Replay,
) -> None:
    database, summary, store = windturbine_replay
    assert summary.outcomes == {"accepted": 10}, summary.rejected
    rows = stored_campaign(database, "windturbine-hss")
    assert [r["status"] for r in rows] == ["accepted"] * 10
    assert [r["taken_at"].date().isoformat() for r in rows][::9] == ["2013-03-11", "2013-04-25"]
    for row in rows:
        result = row["result"]
        assert result["teeth"] == []  # no tooth counts: no per-tooth rows
        assert sorted(m for _, m, _ in result["metrics"]) == [
            "crest", "kurtosis", "peak", "raw_kurtosis", "raw_rms", "rms"]
        assert all(np.isfinite(v) for _, _, v in result["metrics"])
        assert {name for _, name, _, _ in result["curves"]} >= {"pinion_average", "speed_rpm"}
        assert 55 * 60 < result["summary"][0] < 63 * 60  # 55.5-62.7 pulses/s, 1 pulse per rev
    for metric in ("rms", "peak", "crest", "kurtosis", "raw_rms", "raw_kurtosis"):
        days, values = windturbine_trend(database, metric)
        assert len(values) == 10 and days[0] == 0 and days[-1] > 40, metric
    # The data does show the developing fault: the raw vibration's kurtosis rises 3.0 -> 5.4.
    raw = raw_vibration_kurtosis()
    assert raw[-1] > 5 and raw[:5].max() < 3.2 and np.polyfit(days, raw, 1)[0] > 0.03
    again = replay_campaign(WINDTURBINE_EXAMPLE, database.factory, store, progress=False)
    assert again.outcomes == {"unchanged": 10}


def test_real_wind_turbine_stored_raw_kurtosis_trend_rises(windturbine_replay: Replay) -> None:
    """The bearing fault shows in the raw signal's kurtosis, stored per record as ``raw_kurtosis``.

    (The synchronous average's ``kurtosis`` does not rise — averaging removes the bearing's
    non-synchronous impulses — which is why the raw-signal metric exists.)
    """
    days, stored = windturbine_trend(windturbine_replay[0], "raw_kurtosis")
    np.testing.assert_allclose(stored, raw_vibration_kurtosis(), rtol=1e-9)
    assert np.polyfit(days, stored, 1)[0] > 0.03
    assert stored[-3:].mean() > 1.3 * stored[:3].mean()


def test_real_wind_turbine_alarms_on_the_first_record_whose_raw_kurtosis_rises(
    windturbine_replay: Replay,
) -> None:
    """Issue 10: with the default rules the first alarm comes on record 7 (2013-04-10, raw
    kurtosis 3.9 against 3.0–3.1 for records 1–5), the first record clearly above the others, and
    no other alarm opens (the synchronous average's metrics stay flat). Before the short-campaign
    baseline the rule needed 8 baseline records, so it could only alarm on record 10."""
    database = windturbine_replay[0]
    _, stored = windturbine_trend(database, "raw_kurtosis")
    first_risen = int(np.argmax(stored > stored[:5].max() + 0.5))
    with session_scope(database.factory) as session:
        rig = RigRepository(session).get_by_name("windturbine-hss")
        assert rig is not None
        alarms = AlarmRepository(session).list(rig_id=rig.id)
        opened = sorted((a.raised_at, a.indicator, a.severity) for a in alarms)
        record_times = [p.taken_at for p in TrendRepository(session).metric_trend(rig.id, "raw_kurtosis")]
    assert first_risen == 6  # record 7: the data's own first clear rise
    assert [(indicator, severity) for _, indicator, severity in opened] == [("raw_kurtosis", "alarm")]
    assert opened[0][0] == record_times[first_risen]


# -- (c) the same campaign over a CAN bus ------------------------------------------------------
def _udp_pair() -> tuple[can.BusABC, can.BusABC] | None:
    from gearwatch.floor.errors import InputError

    port = random.randint(42_000, 48_000)
    group = random_group()
    try:
        sender = open_bus("udp_multicast", group, port=port)
    except InputError:
        return None
    try:
        return sender, open_bus("udp_multicast", group, port=port)
    except InputError:
        sender.shutdown()
        return None


def _virtual_pair() -> tuple[can.BusABC, can.BusABC]:
    channel = f"gearwatch-integration-{uuid.uuid4().hex}"
    return open_bus("virtual", channel), open_bus("virtual", channel)


def rig_records(campaign: Campaign) -> Iterator[RecordData]:
    """The campaign's records as the rig has them: samples plus time stamp and label."""
    for entry in sorted(campaign.records, key=lambda e: parse_taken_at(e.taken_at)):
        record = read_record(campaign.record_path(entry), campaign)
        record.metadata.update(taken_at=entry.taken_at, label=entry.label)
        yield record


def stream_and_ingest(
    records: list[RecordData],
    buses: tuple[can.BusABC, can.BusABC],
    campaign: Campaign,
    database: Database,
    raw_store: RawStore,
    out: Path,
    *,
    first_record_id: int,
    max_frames_per_s: float | None = None,
) -> list[tuple[AssembledRecord, JobResult]]:
    """Emulator → bus → live assembly (``listen``) → CAN log file → :func:`process_file`.

    The emulator plays in one thread and the listener assembles in another, while this thread
    runs the job on every record as soon as it is closed, one transaction per record, as
    ``gearwatch listen-can`` followed by ``gearwatch watch`` would."""
    from gearwatch.cli.commands.listen_can import save

    sender, receiver = buses
    tach = campaign.tachometer
    assert tach is not None
    closed: queue.Queue[AssembledRecord | None] = queue.Queue()
    stop = threading.Event()
    failures: list[BaseException] = []

    def run_listener() -> None:
        try:
            listen(receiver, closed.put, stop_event=stop,
                   assembler=RecordAssembler(source="integration", keep_accepted_raw_frames=True),
                   max_records=len(records), idle_timeout_s=30.0)
        except BaseException as error:  # reported in the main thread
            failures.append(error)
        finally:
            closed.put(None)

    def run_emulator() -> None:
        try:
            emulate(sender, records, speed=0, first_record_id=first_record_id,
                    max_frames_per_s=max_frames_per_s, tach_channel=tach.channel,
                    tach_kind="pulses" if tach.kind == "pulses" else "pulse_times",
                    pulses_per_rev=tach.pulses_per_rev, tach_shaft=tach.shaft)
        except BaseException as error:
            failures.append(error)
            stop.set()

    listener = threading.Thread(target=run_listener, daemon=True)
    emulator = threading.Thread(target=run_emulator, daemon=True)
    listener.start()
    emulator.start()
    done: list[tuple[AssembledRecord, JobResult]] = []
    try:
        while (assembled := closed.get(timeout=120)) is not None:
            assert assembled.accepted, assembled.reason
            path = save(assembled, out, "blf", first_record_id + len(done))
            with session_scope(database.factory) as session:
                result = process_file(session, path, campaign, raw_store=raw_store,
                                      label=assembled.metadata.get("label", ""))
            done.append((assembled, result))
    finally:
        stop.set()
        emulator.join(timeout=60)
        listener.join(timeout=60)
    if failures:
        raise failures[0]
    return done


@pytest.fixture(scope="session")
def can_replay(
    pcm_campaign: Path, fresh_database: Callable[[], Database],
    tmp_path_factory: pytest.TempPathFactory,
) -> tuple[Database, list[tuple[AssembledRecord, JobResult]], str]:
    """The campaign over the virtual bus, its last record over udp_multicast when available."""
    campaign = load_manifest(pcm_campaign)
    database = fresh_database()
    store = RawStore(tmp_path_factory.mktemp("raw-can"))
    out = tmp_path_factory.mktemp("can-records")
    records = list(rig_records(campaign))
    udp = _udp_pair()
    last_bus = "virtual" if udp is None else "udp_multicast"
    virtual = _virtual_pair()
    try:
        done = stream_and_ingest(records[:-1], virtual, campaign, database, store, out,
                                 first_record_id=1)
        # over UDP at most a window of frames is in flight, so a slow listener loses nothing
        done += stream_and_ingest(records[-1:], windowed(*udp) if udp else virtual, campaign,
                                  database, store, out,
                                  first_record_id=len(records),
                                  max_frames_per_s=UDP_FRAMES_PER_S if udp else None)
    finally:
        for bus in (*virtual, *(udp or ())):
            bus.shutdown()
    return database, done, last_bus


def test_campaign_over_can_is_accepted_with_the_rigs_time_stamps(
    can_replay: tuple[Database, list[tuple[AssembledRecord, JobResult]], str],
    pcm_campaign: Path,
) -> None:
    database, done, last_bus = can_replay
    campaign = load_manifest(pcm_campaign)
    assert len(done) == CAMPAIGN_DAYS
    assert [r.outcome for _, r in done] == ["accepted"] * CAMPAIGN_DAYS, [r.reason for _, r in done]
    assert [a.metadata["can_record_id"] for a, _ in done] == [str(i) for i in range(1, 13)]
    assert [a.metadata["can_duplicates_dropped"] for a, _ in done] == ["0"] * CAMPAIGN_DAYS
    rows = stored_campaign(database, campaign.id)
    assert [r["taken_at"] for r in rows] == [parse_taken_at(e.taken_at) for e in campaign.records]
    assert [r["label"] for r in rows] == [e.label for e in campaign.records]
    with session_scope(database.factory) as session:
        files = [r.file_name for r in RecordRepository(session).list(limit=None)]
    assert all(f.endswith(".blf") for f in files), files  # what listen-can writes
    if last_bus != "udp_multicast":
        message = "udp_multicast is not available here: the last record went over virtual too"
        if IN_CI:
            pytest.fail(message)
        pytest.skip(message)


def test_can_replay_stores_exactly_what_the_file_replay_stores(
    file_replay: Replay,
    can_replay: tuple[Database, list[tuple[AssembledRecord, JobResult]], str],
    pcm_campaign: Path,
) -> None:
    """Record by record, every stored per-tooth indicator, metric, curve and alarm is equal
    (``==`` on floats, bytes on curves), on the same backend."""
    campaign = load_manifest(pcm_campaign)
    from_files = stored_campaign(file_replay[0], campaign.id)
    over_can = stored_campaign(can_replay[0], campaign.id)
    assert len(from_files) == len(over_can) == CAMPAIGN_DAYS
    for day, (expected, got) in enumerate(zip(from_files, over_can, strict=True), start=1):
        assert got["status"] == expected["status"] == "accepted", day
        # the change indicator from the fourth record on (three reference records before it)
        expected_indicators = TOOTH_INDICATORS + (HISTORY_TOOTH_INDICATORS if day > 3 else ())
        assert len(got["result"]["teeth"]) == 20 * len(expected_indicators), day
        for key in expected:
            if key == "result":
                for part in expected["result"]:
                    assert got["result"][part] == expected["result"][part], (day, part)
            else:
                assert got[key] == expected[key], (day, key)
    alarms = stored_alarms(file_replay[0], campaign.rig.id)
    assert alarms and stored_alarms(can_replay[0], campaign.rig.id) == alarms
