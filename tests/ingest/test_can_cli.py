"""``gearwatch emulate-can`` → virtual bus → ``gearwatch listen-can``: files, index, errors."""

from __future__ import annotations

import json
import threading
import time
import uuid
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from gearwatch.cli.main import main
from ingest.manifest import load_manifest
from ingest.sources import read_record

FS_HZ = 10_000.0


def wait_for_virtual_listener(channel: str, listener: threading.Thread) -> None:
    """Block until a bus is attached to the ``virtual`` channel (frames sent on a virtual bus
    before the listener's bus exists are lost), however slow the machine is."""
    from can.interfaces import virtual

    deadline = time.monotonic() + 120  # a bound on a hang, not a speed requirement
    while True:
        with virtual.channels_lock:
            if virtual.channels.get(channel):
                return
        assert listener.is_alive(), "listen-can ended before it opened its bus"
        assert time.monotonic() < deadline, "listen-can never opened its bus"
        time.sleep(0.01)


def write_campaign(root: Path, n_records: int = 2) -> Path:
    rng = np.random.default_rng(5)
    records = []
    for index in range(n_records):
        n = 3_000 + 100 * index
        np.savez(
            root / f"day{index}.npz",
            acc=np.sin(np.arange(n) / 5.0) + 0.05 * rng.standard_normal(n),
            tach=np.arange(1, 30) / 10.0 + 1e-3 * index,
            sample_rate_hz=np.float64(FS_HZ),
        )
        records.append(
            {"file": f"day{index}.npz", "taken_at": f"2026-05-0{index + 1}T10:00:00+00:00", "label": f"d{index}"}
        )
    manifest = {
        "campaign": {"id": "can-cli", "description": "CLI test"},
        "rig": {"id": "rig-can"},
        "acquisition": {"sample_rate_hz": FS_HZ},
        "tachometer": {"channel": "tach", "kind": "pulse_times", "pulses_per_rev": 3},
        "channels": [
            {"name": "acc", "kind": "accelerometer", "unit": "g"},
            {"name": "tach", "kind": "tachometer"},
        ],
        "records": records,
    }
    path = root / "campaign.toml"
    path.write_bytes(tomli_w.dumps(manifest).encode())
    return path


@pytest.mark.parametrize("file_format", ["blf", "npz"])
def test_emulate_then_listen_writes_records_readable_by_the_registry(
    tmp_path: Path, file_format: str, capsys: pytest.CaptureFixture[str]
) -> None:
    manifest = write_campaign(tmp_path)
    channel = f"cli-{uuid.uuid4().hex}"
    out = tmp_path / "out"
    results: list[int] = []
    listener = threading.Thread(
        target=lambda: results.append(
            main(
                ["listen-can", "--interface", "virtual", "--channel", channel, "--out", str(out),
                 "--format", file_format, "--max-records", "2", "--idle-timeout", "120"]
            )
        )
    )
    listener.start()
    wait_for_virtual_listener(channel, listener)
    assert main(["emulate-can", "--campaign", str(manifest), "--interface", "virtual",
                 "--channel", channel, "--speed", "0"]) == 0
    listener.join(timeout=60)
    assert results == [0]
    printed = capsys.readouterr().out
    assert "record 1: day0.npz" in printed and "record 2: day1.npz" in printed
    assert "2 accepted, 0 rejected" in printed
    index = [json.loads(line) for line in (out / "records.jsonl").read_text().splitlines()]
    assert [e["status"] for e in index] == ["accepted", "accepted"]
    assert [e["metadata"]["label"] for e in index] == ["d0", "d1"]
    assert index[1]["metadata"]["can_start_time"] == "2026-05-02T10:00:00.000000+00:00"
    campaign = load_manifest(manifest)
    for entry, day in zip(index, range(2), strict=True):
        assert entry["file"].endswith(f".{file_format}")
        got = read_record(out / entry["file"], campaign)
        sent = read_record(tmp_path / f"day{day}.npz", campaign)
        acc = np.asarray(sent.channels["acc"])
        np.testing.assert_allclose(got.channels["acc"], acc, atol=np.ptp(acc) / (4 * 32766) * 1.000001)
        np.testing.assert_allclose(got.channels["tach"], sent.channels["tach"], atol=1e-9)
        assert got.sample_rate_hz == FS_HZ


def test_listen_writes_a_rejected_record_with_its_raw_frames(tmp_path: Path) -> None:
    from gearwatch.floor.campaign import RecordData
    from ingest.can import protocol as p
    from ingest.can.emulator import record_frames
    from ingest.can.live import open_bus
    from ingest.can.logs import iter_can_log

    channel = f"cli-{uuid.uuid4().hex}"
    out = tmp_path / "out"
    frames = [m for _, m in record_frames(RecordData({"acc": np.arange(900.0)}, FS_HZ), record_id=77)]
    blocks = [i for i, m in enumerate(frames) if m.arbitration_id == p.SAMPLE_BLOCK_ID]
    frames.pop(blocks[4])
    results: list[int] = []
    listener = threading.Thread(
        target=lambda: results.append(
            main(["listen-can", "--interface", "virtual", "--channel", channel, "--out", str(out),
                  "--max-records", "1", "--idle-timeout", "120"])
        )
    )
    listener.start()
    wait_for_virtual_listener(channel, listener)
    bus = open_bus("virtual", channel)
    for msg in frames:
        bus.send(msg)
    listener.join(timeout=60)
    bus.shutdown()
    assert results == [0]
    (entry,) = [json.loads(line) for line in (out / "records.jsonl").read_text().splitlines()]
    assert entry["status"] == "rejected"
    assert "sequence number(s) 4 missing" in entry["reason"]
    assert entry["file"].startswith("rejected/") and entry["file"].endswith(".blf")
    stored = list(iter_can_log(out / entry["file"]))
    assert [bytes(m.data) for m in stored] == [bytes(m.data) for m in frames]


def test_cli_errors_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    manifest = write_campaign(tmp_path, 1)
    assert main(["emulate-can", "--campaign", str(manifest), "--interface", "nosuch"]) == 2
    assert "gearwatch: error: cannot open CAN bus nosuch:gearwatch" in capsys.readouterr().err
    assert main(["emulate-can", "--campaign", str(manifest), "--speed", "-1"]) == 2
    assert "--speed must be >= 0" in capsys.readouterr().err
    assert main(["emulate-can", "--campaign", str(manifest), "--bus-option", "nokey"]) == 2
    assert "expected KEY=VALUE" in capsys.readouterr().err
    assert main(["listen-can", "--out", str(tmp_path / "o"), "--max-records", "0"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--max-records must be >= 1" in err
