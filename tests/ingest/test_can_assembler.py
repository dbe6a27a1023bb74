"""RecordAssembler: round trip through the emulator's frames, gaps, duplicates, lost control frames."""

from __future__ import annotations

import datetime as dt
import json
from pathlib import Path

import can
import numpy as np

from gearwatch.floor.campaign import RecordData
from ingest.can import protocol as p
from ingest.can.assembler import AssembledRecord, RecordAssembler
from ingest.can.emulator import record_frames
from ingest.can.logs import iter_can_log, write_can_log

FS_HZ = 20_000.0
TAKEN_AT = "2026-03-04T05:06:07.123456+00:00"


def make_record(n_samples: int = 6_000, seed: int = 0) -> RecordData:
    rng = np.random.default_rng(seed)
    t = np.arange(n_samples) / FS_HZ
    return RecordData(
        channels={
            "acc1": 3.0 * np.sin(2 * np.pi * 437 * t) + 0.2 * rng.standard_normal(n_samples),
            "acc2": 0.01 * rng.standard_normal(n_samples) - 7.0,
            # 23.7 edges/s with jitter: pulse times in seconds after the first sample
            "tach": np.cumsum(1 / 23.7 + 1e-4 * rng.standard_normal(int(23.7 * n_samples / FS_HZ))),
        },
        sample_rate_hz=FS_HZ,
        source="test",
        metadata={"taken_at": TAKEN_AT, "label": "day 3 ✓"},
    )


def frames_of(record: RecordData, record_id: int = 11, **options: object) -> list[can.Message]:
    options.setdefault("tach_channel", "tach")
    options.setdefault("tach_kind", "pulse_times")
    options.setdefault("pulses_per_rev", 2)
    return [m for _, m in record_frames(record, record_id=record_id, **options)]  # type: ignore[arg-type]


def assemble(frames: list[can.Message], **options: bool) -> list[AssembledRecord]:
    assembler = RecordAssembler(source="unit", **options)
    return assembler.feed_many(frames) + assembler.flush()


def assert_same_record(got: RecordData, sent: RecordData) -> None:
    assert list(got.channels) == list(sent.channels)
    assert got.sample_rate_hz == sent.sample_rate_hz
    for name in ("acc1", "acc2"):
        x = sent.channels[name]
        half_count = (x.max() - x.min()) / (4 * p.MAX_COUNT)  # the documented bound: scale / 2
        error = np.abs(got.channels[name] - x).max()
        assert error <= half_count * (1 + 1e-9), (name, error, half_count)
        assert error > half_count / 100  # int16 quantisation did happen (the test can fail)
    np.testing.assert_allclose(got.channels["tach"], sent.channels["tach"], rtol=0, atol=0.5e-9 + 1e-15)


def test_round_trip_gives_back_samples_within_half_a_count_and_edges_within_1_ns() -> None:
    sent = make_record()
    out = assemble(frames_of(sent))
    assert [r.status for r in out] == ["accepted"]
    got = out[0].record
    assert got is not None and out[0].reason is None
    assert_same_record(got, sent)
    assert got.metadata["label"] == "day 3 ✓"
    assert got.metadata["taken_at"] == TAKEN_AT
    assert got.metadata["can_record_id"] == "11"
    assert got.metadata["can_start_time"] == "2026-03-04T05:06:07.123456+00:00"
    assert got.metadata["can_tach_channel"] == "tach"
    assert got.metadata["can_pulses_per_rev"] == "2"
    assert json.loads(got.metadata["can_channel_kinds"])["tach"] == "tachometer_pulse_times"
    assert out[0].raw_frames == []  # accepted: raw frames not kept unless asked


def test_waveform_tach_travels_as_sample_blocks() -> None:
    sent = make_record()
    sent.channels["tach"] = np.where((np.arange(6_000) % 400) < 40, 5.0, 0.0)
    out = assemble(frames_of(sent, tach_kind="pulses"))
    got = out[0].record
    assert got is not None
    # two-level signal: min and max map exactly onto counts -32766 and 32766
    np.testing.assert_allclose(got.channels["tach"], sent.channels["tach"], atol=1e-12)
    assert json.loads(got.metadata["can_channel_kinds"])["tach"] == "tachometer_waveform"


def test_a_dropped_sample_block_rejects_the_record_naming_the_sequence_and_keeps_raw_frames() -> None:
    frames = frames_of(make_record())
    blocks = [i for i, m in enumerate(frames) if m.arbitration_id == p.SAMPLE_BLOCK_ID]
    acc2_blocks = [i for i in blocks if frames[i].data[2] == 1]
    dropped = acc2_blocks[41]
    kept = frames[:dropped] + frames[dropped + 1 :]
    (result,) = assemble(kept)
    assert result.status == "rejected" and result.record is None
    assert result.reason is not None
    assert "gap in channel 1 ('acc2')" in result.reason
    assert "sequence number(s) 41 missing (1 frame(s))" in result.reason
    assert result.raw_frames == kept  # every received frame, in order, for storage
    assert result.metadata["can_record_id"] == "11"


def test_several_dropped_blocks_are_listed_as_ranges() -> None:
    frames = frames_of(make_record())
    acc1 = [i for i, m in enumerate(frames) if m.arbitration_id == p.SAMPLE_BLOCK_ID and m.data[2] == 0]
    drop = {acc1[i] for i in (5, 6, 7, 100)}
    (result,) = assemble([m for i, m in enumerate(frames) if i not in drop])
    assert result.reason is not None and "5-7, 100 missing (4 frame(s))" in result.reason


def test_first_block_lost_is_a_gap() -> None:
    frames = frames_of(make_record())
    first_block = next(i for i, m in enumerate(frames) if m.arbitration_id == p.SAMPLE_BLOCK_ID)
    (result,) = assemble(frames[:first_block] + frames[first_block + 1 :])
    assert result.status == "rejected"
    assert result.reason is not None and "sequence number(s) 0 missing" in result.reason


def test_last_block_lost_is_caught_by_the_record_stop_counts() -> None:
    frames = frames_of(make_record())
    last_block = max(i for i, m in enumerate(frames) if m.arbitration_id == p.SAMPLE_BLOCK_ID)
    (result,) = assemble(frames[:last_block] + frames[last_block + 1 :])
    assert result.status == "rejected"
    assert result.reason is not None
    assert "RecordStop announces 400 SampleBlock frames, 399 received" in result.reason


def test_a_dropped_tach_frame_is_a_gap() -> None:
    frames = frames_of(make_record())
    tach = [i for i, m in enumerate(frames) if m.arbitration_id == p.TACH_EDGES_ID]
    assert len(tach) >= 3
    (result,) = assemble([m for i, m in enumerate(frames) if i != tach[1]])
    assert result.reason is not None
    assert "gap in channel 2 ('tach') TachEdges frames: sequence number(s) 1 missing" in result.reason


def test_duplicate_frames_are_dropped_and_counted() -> None:
    sent = make_record()
    frames = frames_of(sent)
    block = next(i for i, m in enumerate(frames) if m.arbitration_id == p.SAMPLE_BLOCK_ID) + 10
    tach = next(i for i, m in enumerate(frames) if m.arbitration_id == p.TACH_EDGES_ID)
    info = 1
    doubled = []
    for i, m in enumerate(frames):
        doubled.append(m)
        if i in (block, tach, info, 0):
            doubled.append(m)
    assembler = RecordAssembler()
    (result,) = assembler.feed_many(doubled)
    assert result.status == "accepted" and result.record is not None
    assert result.metadata["can_duplicates_dropped"] == "4"
    assert assembler.stats.duplicates_dropped == 4
    assert_same_record(result.record, sent)
    # a repeated RecordStop after the record closed is a duplicate too, not a stray frame
    assert assembler.feed(frames[-1]) == []
    assert assembler.flush() == [] and assembler.stats.duplicates_dropped == 5


def test_two_different_frames_with_one_sequence_number_reject_the_record() -> None:
    frames = frames_of(make_record())
    block = next(i for i, m in enumerate(frames) if m.arbitration_id == p.SAMPLE_BLOCK_ID) + 3
    altered = bytearray(frames[block].data)
    altered[10] ^= 0xFF
    forged = p.fd_message(p.SAMPLE_BLOCK_ID, bytes(altered))
    (result,) = assemble([*frames[: block + 1], forged, *frames[block + 1 :]])
    sequence = int.from_bytes(frames[block].data[:2], "little")
    channel = frames[block].data[2]
    assert result.reason is not None
    assert f"channel {channel} " in result.reason
    assert f"different frames with the same sequence number(s) {sequence}" in result.reason


def test_reordered_frames_are_put_back_in_sequence_order() -> None:
    sent = make_record()
    frames = frames_of(sent)
    blocks = [i for i, m in enumerate(frames) if m.arbitration_id == p.SAMPLE_BLOCK_ID]
    a, b = blocks[20], blocks[23]
    frames[a], frames[b] = frames[b], frames[a]
    (result,) = assemble(frames)
    assert result.record is not None
    assert_same_record(result.record, sent)


def test_sequence_counter_wraps_after_65536_blocks() -> None:
    n = (p.SEQUENCE_MODULUS + 10) * p.SAMPLES_PER_BLOCK
    ramp = (np.arange(n) % 1000).astype(np.float64)
    sent = RecordData({"acc": ramp}, sample_rate_hz=FS_HZ)
    frames = [m for _, m in record_frames(sent, record_id=1)]
    (result,) = assemble(frames)
    assert result.record is not None
    np.testing.assert_allclose(result.record.channels["acc"], ramp, atol=1000 / (4 * p.MAX_COUNT))
    # a block lost after the wrap is named by its sequence number (mod 65536)
    blocks = [i for i, m in enumerate(frames) if m.arbitration_id == p.SAMPLE_BLOCK_ID]
    lost = blocks[p.SEQUENCE_MODULUS + 3]
    (result,) = assemble(frames[:lost] + frames[lost + 1 :])
    assert result.reason is not None and "sequence number(s) 3 missing" in result.reason


def test_lost_record_start_reports_the_frames_as_orphans() -> None:
    first = frames_of(make_record(), record_id=1)
    second = frames_of(make_record(seed=1), record_id=2)
    out = assemble(first[1:] + second)
    assert [r.status for r in out] == ["rejected", "accepted"]
    assert out[0].reason is not None and "RecordStart of record 1 missing" in out[0].reason
    assert len(out[0].raw_frames) == len(first) - 1
    assert out[1].record is not None and out[1].metadata["can_record_id"] == "2"


def test_lost_record_stop_rejects_the_record_when_the_next_one_starts() -> None:
    first = frames_of(make_record(), record_id=1)
    second = frames_of(make_record(seed=1), record_id=2)
    out = assemble(first[:-1] + second)
    assert [r.status for r in out] == ["rejected", "accepted"]
    assert out[0].reason == "record 1: no RecordStop before RecordStart of record 2 (RecordStop lost?)"
    assert out[0].raw_frames == first[:-1]


def test_stream_ending_inside_a_record_rejects_it_on_flush() -> None:
    frames = frames_of(make_record())
    out = assemble(frames[: len(frames) // 2])
    assert [r.status for r in out] == ["rejected"]
    assert out[0].reason is not None and "stream ended before RecordStop" in out[0].reason


def test_missing_channel_info_and_metadata_chunks_reject() -> None:
    frames = frames_of(make_record())
    info = [i for i, m in enumerate(frames) if m.arbitration_id == p.CHANNEL_INFO_ID]
    (result,) = assemble([m for i, m in enumerate(frames) if i != info[1]])
    assert result.reason is not None and "ChannelInfo missing for channel id(s) [1]" in result.reason
    meta = [i for i, m in enumerate(frames) if m.arbitration_id == p.RECORD_META_ID]
    (result,) = assemble([m for i, m in enumerate(frames) if i != meta[0]])
    assert result.reason is not None and "RecordMeta chunk(s) [0]" in result.reason


def test_aborted_record_is_rejected() -> None:
    (result,) = assemble(frames_of(make_record(), aborted=True))
    assert result.reason is not None and "aborted" in result.reason


def test_foreign_frames_on_the_bus_are_ignored() -> None:
    sent = make_record()
    frames = frames_of(sent)
    noise = [
        can.Message(arbitration_id=0x123, data=b"\x01\x02", is_extended_id=False),
        can.Message(arbitration_id=p.SAMPLE_BLOCK_ID, data=bytes(8), is_extended_id=True),
        can.Message(is_error_frame=True),
    ]
    assembler = RecordAssembler()
    (result,) = assembler.feed_many(frames[:50] + noise + frames[50:])
    assert result.record is not None
    assert_same_record(result.record, sent)
    assert assembler.stats.foreign_frames == 3
    assert assembler.stats.frames == len(frames) + 3


def test_nan_and_infinities_survive_the_bus() -> None:
    sent = make_record()
    sent.channels["acc1"][[5, 6]] = np.nan
    sent.channels["acc1"][7] = np.inf
    sent.channels["acc2"][8] = -np.inf
    (result,) = assemble(frames_of(sent))
    got = result.record
    assert got is not None
    assert np.flatnonzero(np.isnan(got.channels["acc1"])).tolist() == [5, 6]
    assert got.channels["acc1"][7] == np.inf and got.channels["acc2"][8] == -np.inf


def test_start_time_comes_from_the_argument_when_given() -> None:
    start = dt.datetime(2025, 1, 2, 3, 4, 5, 678_901, tzinfo=dt.UTC)
    (result,) = assemble(frames_of(make_record(), start_time=start))
    assert result.metadata["can_start_time"] == "2025-01-02T03:04:05.678901+00:00"


def test_rejected_raw_frames_written_to_blf_and_candump_read_back_identical(tmp_path: Path) -> None:
    frames = frames_of(make_record(2_000))
    (result,) = assemble(frames[:30] + frames[31:])
    assert result.status == "rejected"
    for suffix in (".blf", ".log", ".asc"):
        path = result.write_raw(tmp_path / f"rejected{suffix}")
        back = list(iter_can_log(path))
        assert len(back) == len(result.raw_frames), suffix
        for a, b in zip(back, result.raw_frames, strict=True):
            assert (a.arbitration_id, bytes(a.data), a.is_fd) == (b.arbitration_id, bytes(b.data), True)
        # and the stored file is itself evidence: assembling it gives the same rejection
        (again,) = assemble(back)
        assert again.reason == result.reason


def test_raw_frames_can_be_kept_for_accepted_records_or_never() -> None:
    frames = frames_of(make_record(1_000))
    (kept,) = assemble(frames, keep_accepted_raw_frames=True)
    assert kept.raw_frames == frames
    (lean,) = assemble(frames[:20] + frames[21:], keep_raw_frames=False)
    assert lean.status == "rejected" and lean.raw_frames == []


def test_frames_from_a_bus_whose_name_ends_in_digits_can_be_logged(tmp_path: Path) -> None:
    """python-can's BLF/ASC writers take the channel number from the name's trailing digits."""
    frames = frames_of(make_record(600))
    for msg in frames:
        msg.channel = "rig-20250101123456"
    for suffix in (".blf", ".asc", ".log"):
        back = list(iter_can_log(write_can_log(tmp_path / f"r{suffix}", frames)))
        assert [bytes(m.data) for m in back] == [bytes(m.data) for m in frames]
    assert frames[0].channel == "rig-20250101123456"  # the caller's frames are untouched
