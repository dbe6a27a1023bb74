"""CAN log readers (BLF, ASC, candump .log): the shared round-trip base plus CAN-specific checks.

The logs are written here independently of ``ingest.can``: frames encoded signal by signal
with cantools from the DBC file, stored with python-can's own writers.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, ClassVar

import can
import cantools
import numpy as np
import pytest

from gearwatch.floor.errors import RecordFormatError
from ingest.can.logs import read_can_log_records, write_can_log
from ingest.sources import read_record
from tests.ingest.roundtrip import TACH_CHANNEL, RoundTripBase, make_campaign

DBC_PATH = Path(__file__).resolve().parents[2] / "ingest" / "can" / "gearwatch.dbc"


def _u64_text(text: bytes, size: int) -> list[int]:
    padded = text.ljust(size, b"\0")
    return [int.from_bytes(padded[i : i + 8], "little") for i in range(0, size, 8)]


def protocol_frames(
    channels: dict[str, np.ndarray], sample_rate_hz: float, record_id: int = 1
) -> list[can.Message]:
    """The rig protocol written from the DBC alone (no ingest.can code): one record.

    A channel whose length differs from the first channel's is sent as tachometer pulse times.
    """
    db = cantools.database.load_file(DBC_PATH)
    assert isinstance(db, cantools.database.can.Database)
    names = list(channels)
    n = len(channels[names[0]])
    frames: list[can.Message] = []
    t = 0.0

    def add(name: str, signals: dict[str, Any]) -> None:
        nonlocal t
        message = db.get_message_by_name(name)
        data = message.encode(signals, scaling=False)
        frames.append(
            can.Message(
                timestamp=1_700_000_000.0 + t,
                arbitration_id=message.frame_id,
                data=data,
                is_extended_id=False,
                is_fd=True,
                bitrate_switch=True,
            )
        )
        t += 1e-5

    pulse_ids = [i for i, name in enumerate(names) if len(channels[name]) != n]
    add(
        "RecordStart",
        {
            "RecordId": record_id,
            "ProtocolVersion": 1,
            "ChannelCount": len(names),
            "PulsesPerRev": 1,
            "SampleRate": sample_rate_hz,
            "StartTime": 1_700_000_000_000_000,
            "TachChannelId": pulse_ids[0] if pulse_ids else 255,
            "TachShaft": 0,
            "MetadataBytes": 0,
        },
    )
    blocks = tach_frames = edges = samples = 0
    data_frames: list[tuple[str, dict[str, Any]]] = []
    for channel_id, name in enumerate(names):
        x = np.asarray(channels[name], dtype=np.float64)
        if channel_id in pulse_ids:
            kind, scale, offset = 2, 1.0, 0.0
            for sequence, start in enumerate(range(0, len(x), 8)):
                chunk = x[start : start + 8]
                signals = {
                    "Sequence": sequence,
                    "ChannelId": channel_id,
                    "EdgeCount": len(chunk),
                    "FirstEdgeIndex": start,
                    "Revolution": start,
                }
                for k in range(8):
                    signals[f"EdgeTime{k}"] = round(float(chunk[k]) * 1e9) if k < len(chunk) else 0
                data_frames.append(("TachEdges", signals))
                tach_frames += 1
            edges += len(x)
        else:
            kind = 1 if name == TACH_CHANNEL else 0
            finite = x[np.isfinite(x)]
            low, high = float(finite.min()), float(finite.max())
            offset = (low + high) / 2
            scale = (high - low) / 65532 if high > low else 1.0
            counts = np.full(x.shape, -32768, dtype=np.int64)
            counts[np.isfinite(x)] = np.rint((finite - offset) / scale)
            counts[x == np.inf] = 32767
            counts[x == -np.inf] = -32767
            for sequence, start in enumerate(range(0, len(x), 30)):
                block = counts[start : start + 30]
                signals = {"Sequence": sequence % 65536, "ChannelId": channel_id, "SampleCount": len(block)}
                signals.update({f"Sample{k:02d}": int(block[k]) if k < len(block) else 0 for k in range(30)})
                data_frames.append(("SampleBlock", signals))
                blocks += 1
            samples += len(x)
        info: dict[str, Any] = {
            "RecordId": record_id,
            "ChannelId": channel_id,
            "ChannelKind": kind,
            "Scale": scale,
            "Offset": offset,
            "Unit": _u64_text(b"g", 8)[0],
        }
        info.update({f"Name{k}": v for k, v in enumerate(_u64_text(name.encode(), 32))})
        add("ChannelInfo", info)
    for name, signals in data_frames:
        add(name, signals)
    add(
        "RecordStop",
        {
            "RecordId": record_id,
            "BlockFrameCount": blocks,
            "TachFrameCount": tach_frames,
            "TachEdgeCount": edges,
            "SampleCount": samples,
            "StopReason": 0,
        },
    )
    return frames


def _write_with_python_can(path: Path, frames: list[can.Message]) -> None:
    writer: can.io.generic.MessageWriter
    if path.suffix == ".blf":
        writer = can.BLFWriter(path)
    elif path.suffix == ".asc":
        writer = can.ASCWriter(path)
    else:
        writer = can.CanutilsLogWriter(path, channel="can0")
    with writer:
        for msg in frames:
            writer.on_message_received(msg)


class CanLogRoundTrip(RoundTripBase):
    rate_in_file = "always"  # RecordStart carries the rate
    # int16 on the bus: error ≤ half a count = (max − min) / 131064 ≈ 4.3e-5 for these ±2.8 signals
    atol: ClassVar[float] = 5e-5
    rtol: ClassVar[float] = 0.0
    memory_test_samples = 30_000  # tracemalloc makes python-can's text parsers slow

    def write(self, path: Path, channels: dict[str, np.ndarray], sample_rate_hz: float | None) -> None:
        assert sample_rate_hz is not None
        _write_with_python_can(path, protocol_frames(channels, sample_rate_hz))


# The samples travel as int16 but a record is float64 (8 B per sample): the returned
# channels alone are 8 / (bytes per sample stored) times the record. Assembling adds one
# copy of the 64-byte payloads (2.1 B per sample) on top.


class TestBlfRoundTrip(CanLogRoundTrip):
    suffix = ".blf"
    # Uncompressed BLF CAN FD object: 32 B headers + 40 B frame fields + 64 B data per 30 samples.
    decompressed_bytes_per_sample = 4
    max_read_peak_ratio = 3.5  # float64 output alone is 2x


class TestAscRoundTrip(CanLogRoundTrip):
    suffix = ".asc"


class TestCandumpLogRoundTrip(CanLogRoundTrip):
    suffix = ".log"
    max_read_peak_ratio = 2.5  # hex text is ~5.4 B per sample: float64 output alone is 1.5x


@pytest.mark.parametrize("suffix", [".blf", ".asc", ".log"])
def test_log_with_a_lost_frame_is_refused_naming_the_gap(tmp_path: Path, suffix: str) -> None:
    signals = {"acc1": np.sin(np.arange(3_000) / 7.0), "tach": np.arange(1, 20) / 19.0}
    frames = protocol_frames(signals, 10_000.0)
    blocks = [i for i, m in enumerate(frames) if m.arbitration_id == 0x0C0]
    path = tmp_path / f"gap{suffix}"
    write_can_log(path, frames[: blocks[9]] + frames[blocks[9] + 1 :])
    campaign = make_campaign(tmp_path, ("acc1", "tach"), sample_rate_hz=None, tach_kind="pulse_times")
    with pytest.raises(RecordFormatError) as error:
        read_record(path, campaign)
    message = str(error.value)
    assert message.startswith(str(path))
    assert "gap in channel 0 ('acc1') SampleBlock frames: sequence number(s) 9 missing" in message


def test_log_with_two_records_is_refused_and_read_in_full_by_the_records_api(tmp_path: Path) -> None:
    signals = {"acc1": np.cos(np.arange(600) / 3.0), "tach": np.arange(1, 5) / 5.0}
    frames = protocol_frames(signals, 1_000.0, record_id=1) + protocol_frames(signals, 1_000.0, record_id=2)
    path = write_can_log(tmp_path / "two.blf", frames)
    campaign = make_campaign(tmp_path, ("acc1", "tach"), sample_rate_hz=None, tach_kind="pulse_times")
    with pytest.raises(RecordFormatError, match="holds 2 records"):
        read_record(path, campaign)
    records = read_can_log_records(path)
    assert [r.metadata["can_record_id"] for r in records] == ["1", "2"]
    assert all(r.accepted for r in records)


def test_manifest_kind_must_match_the_channel_kind_on_can(tmp_path: Path) -> None:
    signals = {"acc1": np.cos(np.arange(600) / 3.0), "tach": np.arange(1, 5) / 5.0}
    path = write_can_log(tmp_path / "r.log", protocol_frames(signals, 1_000.0))
    campaign = make_campaign(tmp_path, ("acc1", "tach"), sample_rate_hz=None, tach_kind="pulses")
    with pytest.raises(RecordFormatError, match="'tach' is tachometer_pulse_times on CAN"):
        read_record(path, campaign)


def test_a_log_of_other_can_traffic_is_no_record(tmp_path: Path) -> None:
    frames = [can.Message(arbitration_id=0x321, data=bytes(8), is_extended_id=False) for _ in range(5)]
    path = write_can_log(tmp_path / "other.asc", frames)
    campaign = make_campaign(tmp_path, ("acc1",), sample_rate_hz=None)
    with pytest.raises(RecordFormatError, match="no record of the gearwatch CAN protocol"):
        read_record(path, campaign)


def test_record_metadata_from_the_log(tmp_path: Path) -> None:
    signals = {"acc1": np.cos(np.arange(600) / 3.0), "tach": np.arange(1, 5) / 5.0}
    path = write_can_log(tmp_path / "r.blf", protocol_frames(signals, 1_000.0, record_id=42))
    campaign = make_campaign(tmp_path, ("acc1", "tach"), sample_rate_hz=None, tach_kind="pulse_times")
    record = read_record(path, campaign)
    assert record.metadata["can_record_id"] == "42"
    assert record.metadata["taken_at"] == "2023-11-14T22:13:20.000000+00:00"
    assert record.metadata["format"] == "blf"
    assert json.loads(record.metadata["can_channel_kinds"]) == {
        "acc1": "accelerometer",
        "tach": "tachometer_pulse_times",
    }
