"""Crashers the fuzz harness found, kept as regression tests (issue 12)."""

from __future__ import annotations

import numpy as np

from gearwatch.floor.campaign import RecordData
from ingest.can import protocol as p
from ingest.can.assembler import RecordAssembler
from ingest.can.emulator import record_frames


def _frames() -> list:  # type: ignore[type-arg]
    t = np.arange(600) / 2000.0
    record = RecordData(
        channels={"acc": np.sin(2 * np.pi * 50 * t),
                  "tach": (np.sin(2 * np.pi * 25 * t) > 0.95) * 5.0},
        sample_rate_hz=2000.0,
    )
    return [m for _, m in record_frames(record, record_id=7, tach_channel="tach")]


def _assemble(frames: list) -> list:  # type: ignore[type-arg]
    assembler = RecordAssembler(source="regression")
    out = []
    for message in frames:
        out.extend(assembler.feed(message))
    return out + assembler.flush("end")


def _with_payload(message, payload: bytes):  # type: ignore[no-untyped-def]
    return type(message)(arbitration_id=message.arbitration_id, data=payload[:64], is_fd=True,
                         is_extended_id=False, bitrate_switch=True)


def test_a_record_start_time_past_year_9999_rejects_the_record() -> None:
    """Found by the long fuzz run: a RecordStart payload shifted by one byte gave a StartTime
    in year 16536 and ``ValueError: year is out of range`` stopped the receiver."""
    frames = _frames()
    assert frames[0].arbitration_id == p.RECORD_START_ID
    frames[0] = _with_payload(frames[0], b"\x00" + bytes(frames[0].data))
    records = _assemble(frames)
    assert records and all(r.status == "rejected" for r in records)
    assert any("StartTime" in r.reason or "invalid" in str(r.metadata) for r in records)


def test_a_bad_last_sample_block_count_rejects_with_a_reason() -> None:
    """Found by the long fuzz run: a last SampleBlock with a count outside 1..30 and no short
    block before it gave ``IndexError`` while naming the short blocks."""
    frames = _frames()
    last_block = max(i for i, m in enumerate(frames) if m.arbitration_id == p.SAMPLE_BLOCK_ID)
    payload = bytearray(frames[last_block].data)
    payload[3] = 0  # SampleCount: u8 after Sequence u16 and ChannelId u8
    assert p.decode(p.SAMPLE_BLOCK_ID, bytes(frames[last_block].data))["SampleCount"] >= 1
    frames[last_block] = _with_payload(frames[last_block], bytes(payload))
    [record] = _assemble(frames)
    assert record.status == "rejected"
    assert "the last block holds 0 samples" in record.reason
