"""``gearwatch replay`` and ``gearwatch watch`` on SQLite and PostgreSQL.

The record-by-record logic is tested with the stand-in analyzer; the command line runs the
real chain on a small simulated campaign (``gearwatch simulate-campaign``).
"""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import pytest
import sqlalchemy as sa

from gearwatch.cli.main import main
from gearwatch.floor.results import TOOTH_INDICATORS, AnalysisParameters
from gearwatch.usecases.replay import replay_campaign
from gearwatch.usecases.watch import FolderWatcher
from ingest.manifest import dump_manifest
from storage.db import session_factory, session_scope
from storage.raw_store import RawStore
from storage.repositories import AlarmRepository, RecordRepository
from tests.gearwatch.jobfixtures import FakeAnalyzer, make_campaign, write_record
from tests.gearwatch.test_jobs import row_counts
from tests.storage import dbfixtures

# The database fixtures (SQLite and PostgreSQL), shared with tests/storage.
_postgres_schema = dbfixtures._postgres_schema
db_url = dbfixtures.db_url
db_engine_migrated = dbfixtures.db_engine_migrated
db_engine = dbfixtures.db_engine
db_session = dbfixtures.db_session


def test_replay_ingests_in_time_order_and_is_idempotent(db_engine: sa.Engine, tmp_path) -> None:
    amplitudes = [1.0] * 8 + [2.0, 2.0, 2.0]
    campaign = make_campaign(tmp_path / "camp", amplitudes, flat=(3,), truncated=(5,))
    # Newest first in the manifest: replay must still go oldest first (alarms need the order).
    manifest = tmp_path / "camp" / "campaign.toml"
    manifest.write_text(dump_manifest(
        dataclasses.replace(campaign, records=tuple(reversed(campaign.records)))))
    factory = session_factory(db_engine)
    store = RawStore(tmp_path / "store")
    analyzer = FakeAnalyzer()
    summary = replay_campaign(manifest, factory, store, analyzer=analyzer, progress=False)
    assert summary.outcomes == {"accepted": 9, "rejected": 2}
    assert [f for f, _ in summary.rejected] == ["day03.wav", "day05.wav"]
    assert "no pulses" in summary.rejected[0][1] and "truncated" in summary.rejected[1][1]
    with session_scope(factory) as session:
        records = RecordRepository(session).list(limit=None)
        assert [r.file_name for r in records] == [f"day{d:02d}.wav" for d in range(11)]
    assert summary.campaign == campaign.id and summary.rig == campaign.rig.id
    lines = summary.lines()
    assert lines[0] == f"campaign {campaign.id} (rig rig-1): 11 record(s): 9 accepted, 2 rejected"

    with session_scope(factory) as session:
        before = row_counts(session)
    again = replay_campaign(manifest, factory, store, analyzer=analyzer, progress=False)
    assert again.outcomes == {"unchanged": 11} and again.alarms_raised == 0
    with session_scope(factory) as session:
        assert row_counts(session) == before

    literal = replay_campaign(manifest, factory, store, AnalysisParameters(mci_form="literal"),
                              analyzer=analyzer, progress=False)
    # Rejected records are tried again with other parameters (and fail again here).
    assert literal.outcomes == {"reprocessed": 9, "rejected": 2}


def test_replay_raises_alarms_and_lists_them(db_engine: sa.Engine, tmp_path) -> None:
    campaign = make_campaign(tmp_path / "camp", [1.0] * 8 + [3.0, 3.0])
    factory = session_factory(db_engine)
    summary = replay_campaign(tmp_path / "camp" / "campaign.toml", factory,
                              RawStore(tmp_path / "store"), analyzer=FakeAnalyzer(),
                              progress=False)
    assert summary.alarms_raised == 20  # mci_depth on every tooth (the stand-in is uniform)
    assert len(summary.open_alarms) == 20
    assert "mci_depth tooth" in summary.open_alarms[0]
    assert "raised 2024-03-10 08:00 UTC" in summary.open_alarms[0]
    with session_scope(factory) as session:
        assert AlarmRepository(session).count(open_only=True) == 20

    # A second campaign on the rig (a later test) that raises nothing: its summary speaks of
    # its own alarms and only counts the rig's others, and the first campaign's still lists its own.
    make_campaign(tmp_path / "later", [1.0] * 10, name="camp-b")
    later = replay_campaign(tmp_path / "later" / "campaign.toml", factory,
                            RawStore(tmp_path / "store"), analyzer=FakeAnalyzer(), progress=False)
    assert later.alarms_raised == 0 and later.open_alarms == [] and later.other_open_alarms == 20
    assert later.lines()[-2].endswith("0 open in this campaign")
    assert "and 20 open in the rig's other campaigns" in later.lines()[-1]
    again = replay_campaign(tmp_path / "camp" / "campaign.toml", factory,
                            RawStore(tmp_path / "store"), analyzer=FakeAnalyzer(), progress=False)
    assert len(again.open_alarms) == 20 and again.other_open_alarms == 0
    assert campaign.id in summary.lines()[0]


def test_watcher_waits_for_files_to_settle_and_ingests_each_once(db_engine: sa.Engine,
                                                                 tmp_path) -> None:
    folder = tmp_path / "drop"
    make_campaign(folder, [1.0, 1.0])
    store = RawStore(folder / "raw-store")  # inside the watched folder: must be ignored
    watcher = FolderWatcher(folder, session_factory(db_engine), store, AnalysisParameters(),
                            analyzer=FakeAnalyzer())
    assert watcher.poll() == []  # first sight: wait for the files to settle
    first = watcher.poll()
    assert sorted(p.name for p, _ in first) == ["day00.wav", "day01.wav"]
    assert all(r.outcome == "accepted" for _, r in first)
    assert watcher.poll() == []
    write_record(folder / "late.wav.part", 1.5)  # still being copied: ignored
    (folder / "late.wav.part").rename(folder / "late.wav")
    assert watcher.poll() == []
    (late,) = watcher.poll()
    assert late[0].name == "late.wav" and late[1].outcome == "accepted"
    assert watcher.poll(settle=False) == []
    assert watcher.counts == {"accepted": 3}


# -- the command line with the real chain --------------------------------------------------------
@pytest.fixture(scope="module")
def simulated_campaign(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("sim") / "campaign"
    code = main(["simulate-campaign", str(folder), "--days", "3", "--seconds", "3",
                 "--seed", "5"])
    assert code == 0
    return folder


@pytest.mark.slow
def test_replay_command_end_to_end(simulated_campaign: Path, db_url: str, db_engine: sa.Engine,
                                   tmp_path, capsys: pytest.CaptureFixture[str]) -> None:
    store = tmp_path / "raw"
    args = ["replay", str(simulated_campaign), "--db", db_url, "--raw-store", str(store)]
    assert main(args) == 0
    captured = capsys.readouterr()
    assert "3 record(s): 3 accepted" in captured.out
    assert "replay sim-seed5" in captured.err  # the progress bar is on stderr
    with session_scope(session_factory(db_engine)) as session:
        records = RecordRepository(session).list()
        assert [r.status for r in records] == ["accepted"] * 3
        result = RecordRepository(session).current_result(records[0].id)
        assert result.parameters["mci_form"] == "robust"
        assert len(RecordRepository(session).tooth_indicators(result.id)) == 20 * len(
            TOOTH_INDICATORS
        )
        curves = {c.name for c in RecordRepository(session).curves(result.id)}
        assert "mci" in curves
    assert len([p for p in store.rglob("*.wav")]) == 3

    assert main([*args, "--no-progress"]) == 0
    assert "3 record(s): 3 unchanged" in capsys.readouterr().out
    params = tmp_path / "params.json"
    params.write_text(json.dumps({"mci_form": "literal"}))
    assert main([*args, "--no-progress", "--params", str(params)]) == 0
    assert "3 record(s): 3 reprocessed" in capsys.readouterr().out


@pytest.mark.slow
def test_replay_defaults_to_gearwatch_db_in_the_working_directory(
    simulated_campaign: Path, tmp_path, monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("GEARWATCH_DATABASE_URL", raising=False)
    monkeypatch.delenv("GEARWATCH_RAW_STORE", raising=False)
    campaign = tmp_path / "c"
    shutil.copytree(simulated_campaign, campaign)
    (campaign / "records" / "day02.wav").write_bytes(b"RIFF garbage")
    assert main(["watch", str(campaign), "--once"]) == 0
    out = capsys.readouterr().out
    assert "records/day02.wav: rejected" in out and "records/day01.wav: accepted" in out
    assert (tmp_path / "gearwatch.db").is_file()
    assert len(list((tmp_path / "raw-store").rglob("*.wav"))) == 3
    assert main(["replay", str(campaign), "--no-progress"]) == 0
    assert "3 record(s): 3 unchanged" in capsys.readouterr().out


def test_replay_command_errors_are_one_line(tmp_path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["replay", str(tmp_path / "nowhere"), "--db", "sqlite://"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("gearwatch: error:") and "campaign.toml" in err
    assert err.count("\n") == 1
    make_campaign(tmp_path / "c", [1.0])
    bad = tmp_path / "p.json"
    bad.write_text(json.dumps({"colour": "red"}))
    assert main(["replay", str(tmp_path / "c"), "--db", "sqlite://", "--params", str(bad)]) == 2
    assert "unknown analysis parameter" in capsys.readouterr().err
    assert main(["watch", str(tmp_path / "c"), "--interval", "0", "--db", "sqlite://"]) == 2


@pytest.mark.slow
def test_replay_of_the_real_wind_turbine_campaign(db_url: str, db_engine: sa.Engine, tmp_path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """10 real records (MAT, pulse-time tachometer, no tooth counts): all accepted, whole-record
    metrics trended, no per-tooth rows; replaying again changes nothing."""
    from storage.models import ToothIndicator
    from storage.repositories import RigRepository, TrendRepository
    from tests.conftest import IN_CI

    repo = Path(__file__).resolve().parents[2]
    example = repo / "examples" / "windturbine-hss"
    shared = repo.parent / "shared" / "data" / "real" / "windturbine-hss"
    if not shared.is_dir():
        if IN_CI:
            pytest.fail(f"{shared} is missing: CI must clone the repository with shared/ beside it")
        pytest.skip(f"{shared} not present")
    args = ["replay", str(example), "--db", db_url, "--raw-store", str(tmp_path / "raw"),
            "--no-progress"]
    assert main(args) == 0
    assert "10 record(s): 10 accepted" in capsys.readouterr().out
    with session_scope(session_factory(db_engine)) as session:
        rig = RigRepository(session).get_by_name("windturbine-hss")
        assert rig is not None and rig.pinion_teeth is None
        kurtosis = TrendRepository(session).metric_trend(rig.id, "kurtosis")
        assert len(kurtosis) == 10 and kurtosis[0].taken_at.isoformat().startswith("2013-03-11")
        assert all(1.0 < p.value < 10.0 for p in kurtosis)
        assert session.scalar(sa.select(sa.func.count()).select_from(ToothIndicator)) == 0
    assert main(args) == 0
    assert "10 record(s): 10 unchanged" in capsys.readouterr().out


def test_replay_with_new_parameters_can_reevaluate_the_alarms(db_engine: sa.Engine,
                                                              tmp_path) -> None:
    campaign = make_campaign(tmp_path / "camp", [1.0] * 8 + [3.0, 3.0])
    manifest = tmp_path / "camp" / "campaign.toml"
    factory = session_factory(db_engine)
    store = RawStore(tmp_path / "store")
    replay_campaign(manifest, factory, store, analyzer=FakeAnalyzer(), progress=False)

    class Halved(FakeAnalyzer):  # "new parameters" that shrink the excursion below warning
        def __call__(self, record, campaign, params, sha, baselines):  # type: ignore[no-untyped-def]
            record.channels["acc"] = record.channels["acc"] / (
                1.0 if float(abs(record.channels["acc"]).max()) < 2.0 else 3.0)
            return super().__call__(record, campaign, params, sha, baselines)

    summary = replay_campaign(manifest, factory, store, AnalysisParameters(samples_per_mesh=32),
                              analyzer=Halved(), progress=False, reevaluate_alarms=True)
    assert summary.outcomes == {"reprocessed": 10} and summary.reevaluated
    assert summary.alarms_raised == 0 and summary.open_alarms == []
    assert "re-evaluated" in summary.lines()[-1]
    with session_scope(factory) as session:
        assert AlarmRepository(session).count() == 0
    assert campaign.id == summary.campaign


@pytest.mark.slow
@pytest.mark.parametrize("stop_signal", ["SIGINT", "SIGINT inherited ignored", "SIGTERM"])
def test_watch_command_ingests_dropped_files_until_interrupted(tmp_path, stop_signal: str) -> None:
    """The real polling loop as a process: a file dropped while it runs is ingested with the
    real chain; Ctrl-C (SIGINT) or SIGTERM (docker stop) ends it with a summary and exit code 0 —
    also when it was started with SIGINT ignored, as a background job of a non-interactive
    shell is (Python then never raises KeyboardInterrupt by itself)."""
    import os
    import signal
    import subprocess
    import sys
    import time

    def ignore_sigint() -> None:
        signal.signal(signal.SIGINT, signal.SIG_IGN)

    folder = tmp_path / "drop"
    make_campaign(folder, [1.0])
    repo = Path(__file__).resolve().parents[2]
    env = {**os.environ, "PYTHONPATH": str(repo), "PYTHONFAULTHANDLER": "1"}
    process = subprocess.Popen(
        [sys.executable, "-m", "gearwatch", "watch", str(folder), "--interval", "0.2",
         "--db", f"sqlite:///{tmp_path / 'w.db'}", "--raw-store", str(tmp_path / "raw")],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=tmp_path,
        preexec_fn=ignore_sigint if stop_signal == "SIGINT inherited ignored" else None,
    )
    try:
        deadline = time.monotonic() + 600  # a bound on a hang on a loaded box, not a speed limit
        engine = sa.create_engine(f"sqlite:///{tmp_path / 'w.db'}")

        def records() -> int:
            try:
                with engine.connect() as connection:
                    return int(connection.execute(sa.text(
                        "SELECT count(*) FROM records WHERE status = 'accepted'")).scalar() or 0)
            except sa.exc.OperationalError:  # not migrated yet
                return 0

        while records() < 1:
            assert time.monotonic() < deadline and process.poll() is None
            time.sleep(0.2)
        # Dropped as a rig should: written under an ignored name, then renamed (a file written
        # in place can look settled to the watcher while the writer is descheduled).
        write_record(folder / "dropped.wav.part", 1.7).rename(folder / "dropped.wav")
        while records() < 2:
            assert time.monotonic() < deadline and process.poll() is None
            time.sleep(0.2)
        engine.dispose()
    finally:
        process.send_signal(signal.SIGTERM if stop_signal == "SIGTERM" else signal.SIGINT)
        try:
            out, err = process.communicate(timeout=120)
        except subprocess.TimeoutExpired:  # say where it hangs
            process.send_signal(signal.SIGABRT)  # PYTHONFAULTHANDLER: every thread's stack
            out, err = process.communicate(timeout=60)
            pytest.fail(f"watch did not stop within 120 s of {stop_signal}; its stacks:\n{err[-6000:]}")
    assert process.returncode == 0, err
    assert "day00.wav: accepted" in out and "dropped.wav: accepted" in out
    assert "ingested: 2 accepted" in out and "open in this campaign: 0" in out
