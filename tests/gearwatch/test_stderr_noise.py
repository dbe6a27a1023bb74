"""Issue 12 item 7: library logging and warnings (nptdms, numpy, h5py, python-can) go through
gearwatch's logging; a failing command prints exactly one line on stderr."""

from __future__ import annotations

import logging
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from nptdms import ChannelObject, TdmsWriter

from tests.gearwatch.jobfixtures import SAMPLE_RATE_HZ, make_campaign


def _truncated_tdms(folder: Path) -> Path:
    n = 8000
    t = np.arange(n) / SAMPLE_RATE_HZ
    acc = np.sqrt(2) * np.sin(2 * np.pi * 50 * t)
    tach = (np.sin(2 * np.pi * 25 * t) > 0.95) * 5.0
    path = folder / "whole.tdms"
    with TdmsWriter(path) as writer:
        for part in range(4):
            cut = slice(part * 2000, (part + 1) * 2000)
            writer.write_segment([
                ChannelObject("g", "acc", acc[cut], properties={"wf_increment": 1 / SAMPLE_RATE_HZ}),
                ChannelObject("g", "tach", tach[cut]),
            ])
    data = path.read_bytes()
    truncated = folder / "truncated.tdms"
    truncated.write_bytes(data[: len(data) // 2])
    return truncated


def _analyze(record: Path, manifest: Path, **env: str) -> subprocess.CompletedProcess[str]:
    import os

    return subprocess.run(
        [sys.executable, "-m", "gearwatch", "analyze", str(record), "--campaign", str(manifest)],
        capture_output=True, text=True, timeout=120, env={**os.environ, **env},
    )


def test_a_truncated_tdms_prints_one_line_not_nptdms_warnings(tmp_path: Path) -> None:
    make_campaign(tmp_path / "camp", [1.0])
    record = _truncated_tdms(tmp_path / "camp")
    done = _analyze(record, tmp_path / "camp" / "campaign.toml")
    assert done.returncode == 2
    assert done.stderr.splitlines() == [done.stderr.strip()], done.stderr
    assert done.stderr.startswith("gearwatch: error:") and "truncated TDMS" in done.stderr
    # Asked for, the library's warnings come through gearwatch's handler, one line each.
    verbose = _analyze(record, tmp_path / "camp" / "campaign.toml", GEARWATCH_LOG_LEVEL="WARNING")
    lines = verbose.stderr.splitlines()
    assert any(line.startswith("gearwatch: WARNING: nptdms.") for line in lines), lines
    assert not any(line.startswith("[nptdms") for line in lines), lines
    assert lines[-1].startswith("gearwatch: error:")


def test_warnings_and_library_records_are_routed_and_one_line(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import gearwatch.floor.logs as logs

    monkeypatch.delenv("GEARWATCH_LOG_LEVEL", raising=False)
    monkeypatch.delenv("GEARWATCH_DEBUG", raising=False)
    root = logging.getLogger()
    for handler in [h for h in root.handlers if isinstance(h, logs.OneLineHandler)]:
        root.removeHandler(handler)  # left by an in-process main() of an earlier test
    logs.configure_cli_logging()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("always")
            np.array([1e300]) ** 2  # numpy: overflow RuntimeWarning
        logging.getLogger("h5py._conv").warning("noise")
        logging.getLogger("can.interfaces").warning("more noise")
        logging.getLogger("psycopg").warning(  # a lost connection, before gearwatch's error
            "error ignored terminating <psycopg.Pipeline [BAD]>: the connection is lost")
        logging.getLogger("gearwatch.test").warning("multi\nline " + "x" * 2000)
        err = capsys.readouterr().err
        lines = err.splitlines()
        assert len(lines) == 1, err
        assert lines[0].startswith("gearwatch: WARNING: gearwatch.test: multi line")
        assert len(lines[0]) <= logs.MAX_LINE_CHARS
    finally:
        root = logging.getLogger()
        for handler in [h for h in root.handlers if isinstance(h, logs.OneLineHandler)]:
            root.removeHandler(handler)
        logging.captureWarnings(False)
        logs._library_level = None


def test_a_reader_that_closes_the_pipe_is_not_an_internal_error() -> None:
    """`gearwatch … | head` closes stdout early: exit quietly (141, as a shell reports SIGPIPE),
    never 'internal error: BrokenPipeError'. The pipe is closed before the command writes."""
    process = subprocess.Popen(
        [sys.executable, "-m", "gearwatch", "simulate", "--print-model"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE,
    )
    assert process.stdout is not None and process.stderr is not None
    process.stdout.close()
    stderr = process.stderr.read().decode()
    process.stderr.close()
    returncode = process.wait(timeout=120)
    assert "internal error" not in stderr and "Traceback" not in stderr, stderr
    assert returncode in (0, 141), (returncode, stderr)
