"""Issue 12 item 3: extreme sample values never overflow, crash or produce invalid JSON.

A sample beyond any sensor's range (1e80, 1e100, 1e300, float32's 3e38) is never an
``OverflowError`` (exit 70) or a ``NaN`` in ``--json``: in the tachometer it is a quality failure
with a reason (exit 2, one line); in an accelerometer it is a glitch, bridged and counted in
``quality`` (issue 10); a large but possible value is analysed and its ``--json`` is strict JSON."""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gearwatch.cli.main import main
from gearwatch.usecases.analyze import MAX_ABS_SAMPLE
from tests.gearwatch.jobfixtures import SAMPLE_RATE_HZ, make_campaign


def strict_json(text: str) -> object:
    """``json.loads`` that refuses the NaN/Infinity tokens Python's json would accept."""

    def refuse(token: str) -> object:
        raise ValueError(f"not JSON: {token}")

    return json.loads(text, parse_constant=refuse)


@pytest.fixture(scope="module")
def campaign(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("extreme") / "camp"
    make_campaign(folder, [1.0])
    return folder / "campaign.toml"


def _write(folder: Path, *, acc_value: float | None = None, tach_value: float | None = None,
           dtype: type = np.float64, fill: float | None = None) -> Path:
    n = 8000
    t = np.arange(n) / SAMPLE_RATE_HZ
    acc = np.sqrt(2) * np.sin(2 * np.pi * 50 * t)
    tach = (np.sin(2 * np.pi * 25 * t) > 0.95) * 5.0
    if fill is not None:
        acc = np.where(np.arange(n) % 2 == 0, fill, -fill) + acc
    if acc_value is not None:
        acc[1234] = acc_value
    if tach_value is not None:
        tach[1234] = tach_value
    path = folder / "extreme.npz"
    np.savez(path, acc=acc.astype(dtype), tach=tach.astype(dtype),
             sample_rate_hz=np.array(float(SAMPLE_RATE_HZ)))
    return path


@pytest.mark.parametrize(
    ("value", "dtype"),
    [(1e80, np.float64), (1e100, np.float64), (-1e300, np.float64), (3e38, np.float32)],
)
def test_an_impossible_accelerometer_sample_is_a_counted_glitch(
    campaign: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], value: float,
    dtype: type,
) -> None:
    """Issue 10 (robust): one impossible sample in an accelerometer channel is a glitch — bridged,
    its revolution left out, counted in ``quality`` — and the record is analysed."""
    record = _write(tmp_path, dtype=dtype, acc_value=value)
    code = main(["analyze", str(record), "--campaign", str(campaign), "--json"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    data = strict_json(captured.out)
    assert isinstance(data, dict)
    assert data["quality"]["glitch_samples"] == 1
    assert data["metrics"]["peak"] < 10


def test_an_impossible_tachometer_sample_is_a_quality_failure_with_a_reason(
    campaign: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    record = _write(tmp_path, tach_value=1e100)
    code = main(["analyze", str(record), "--campaign", str(campaign), "--json"])
    captured = capsys.readouterr()
    assert code == 2, captured.err
    assert captured.out == ""
    assert "beyond any sensor's range" in captured.err and len(captured.err.splitlines()) == 1


@pytest.mark.parametrize("spike", [0.9 * MAX_ABS_SAMPLE, None])
def test_large_possible_values_give_strict_json(
    campaign: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], spike: float | None
) -> None:
    """A spike just under the limit, or a whole record at ±half the limit."""
    record = _write(tmp_path, acc_value=spike) if spike else _write(
        tmp_path, fill=0.5 * MAX_ABS_SAMPLE)
    code = main(["analyze", str(record), "--campaign", str(campaign), "--json"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    data = strict_json(captured.out)
    assert isinstance(data, dict) and data["metrics"]["peak"] is not None


def test_non_finite_results_are_null_in_json() -> None:
    from tests.storage.factories import analysis

    result = analysis()
    channel = result.channels[0]
    teeth = [dataclasses.replace(channel.teeth[0], diff_kurtosis=math.nan), *channel.teeth[1:]]
    metrics = {**channel.metrics, "kurtosis": math.inf}
    broken = dataclasses.replace(
        result, channels=[dataclasses.replace(channel, teeth=teeth, metrics=metrics)])
    data = strict_json(json.dumps(broken.to_json(curves=True), allow_nan=False))
    assert isinstance(data, dict)
    assert data["teeth"][0]["diff_kurtosis"] is None and data["metrics"]["kurtosis"] is None


def test_cli_stderr_is_one_line_for_an_impossible_value(campaign: Path, tmp_path: Path) -> None:
    """In a real process, so that library warnings (numpy overflow) would show."""
    record = _write(tmp_path, tach_value=1e100)
    done = subprocess.run(
        [sys.executable, "-m", "gearwatch", "analyze", str(record), "--campaign", str(campaign),
         "--json"], capture_output=True, text=True, timeout=120,
    )
    assert done.returncode == 2
    assert done.stdout == ""
    assert len(done.stderr.splitlines()) == 1, done.stderr


def test_an_impossible_value_is_stored_rejected_with_its_reason(
    campaign: Path, tmp_path: Path
) -> None:
    from gearwatch.usecases.ingest_file import process_file
    from ingest.manifest import load_manifest
    from storage.db import open_database, session_scope
    from storage.raw_store import RawStore

    record = _write(tmp_path, tach_value=1e100)
    _, factory = open_database(f"sqlite:///{tmp_path / 'db.sqlite'}")
    with session_scope(factory) as session:
        job = process_file(session, record, load_manifest(campaign),
                           raw_store=RawStore(tmp_path / "raw"), taken_at="2026-01-01T00:00:00Z")
    assert job.status == "rejected"
    assert job.reason is not None and "beyond any sensor's range" in job.reason
    assert "internal error" not in job.reason
