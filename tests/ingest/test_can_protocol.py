"""The rig's DBC and the frame codec: the numpy fast path agrees with cantools, quantisation bound."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ingest.can import protocol as p


def test_dbc_declares_every_message_as_64_byte_can_fd_with_the_protocol_ids() -> None:
    db = p.load_dbc()
    ids = {m.name: m.frame_id for m in db.messages}
    assert ids == {
        "TachEdges": p.TACH_EDGES_ID,
        "SampleBlock": p.SAMPLE_BLOCK_ID,
        "RecordStart": p.RECORD_START_ID,
        "ChannelInfo": p.CHANNEL_INFO_ID,
        "RecordMeta": p.RECORD_META_ID,
        "RecordStop": p.RECORD_STOP_ID,
    }
    for message in db.messages:
        assert message.is_fd, message.name
        assert message.length == p.FRAME_BYTES, message.name
        assert not message.is_extended_frame
        for signal in message.signals:
            assert signal.byte_order == "little_endian", (message.name, signal.name)
            assert signal.start + signal.length <= 8 * p.FRAME_BYTES


def test_sample_block_dtype_mirrors_the_dbc_layout() -> None:
    """Each field of the numpy dtype sits at the DBC signal's start bit with its width and sign."""
    message = p.load_dbc().get_message_by_name("SampleBlock")
    signals = {s.name: s for s in message.signals}
    fields = p.SAMPLE_BLOCK_DTYPE.fields
    assert fields is not None
    for field_name, signal_name in (
        ("sequence", "Sequence"),
        ("channel_id", "ChannelId"),
        ("sample_count", "SampleCount"),
    ):
        dtype, offset = fields[field_name][:2]
        signal = signals[signal_name]
        assert (8 * offset, 8 * dtype.itemsize, dtype.kind == "i") == (
            signal.start,
            signal.length,
            signal.is_signed,
        )
    samples_dtype, samples_offset = fields["samples"][:2]
    for k in range(p.SAMPLES_PER_BLOCK):
        signal = signals[f"Sample{k:02d}"]
        assert signal.start == 8 * samples_offset + 16 * k
        assert signal.length == 16 and signal.is_signed
    assert samples_dtype.shape == (p.SAMPLES_PER_BLOCK,)


@settings(max_examples=40, deadline=None)
@given(
    counts=st.lists(st.integers(-32768, 32767), min_size=1, max_size=200),
    channel_id=st.integers(0, 254),
)
def test_fast_decode_equals_cantools_on_the_same_frames(counts: list[int], channel_id: int) -> None:
    payloads = p.encode_sample_blocks(np.array(counts, dtype=np.int16), channel_id)
    fast = p.decode_sample_blocks(b"".join(payloads))
    message = p.load_dbc().get_message_by_frame_id(p.SAMPLE_BLOCK_ID)
    for row, payload in zip(fast, payloads, strict=True):
        reference = message.decode(payload, decode_choices=False)
        assert isinstance(reference, dict)
        assert row["sequence"] == reference["Sequence"]
        assert row["channel_id"] == reference["ChannelId"] == channel_id
        assert row["sample_count"] == reference["SampleCount"]
        assert row["samples"].tolist() == [reference[f"Sample{k:02d}"] for k in range(30)]
    valid = np.concatenate([row["samples"][: row["sample_count"]] for row in fast])
    assert valid.tolist() == counts


def test_sample_blocks_encoded_by_cantools_decode_with_the_fast_path() -> None:
    """The other direction: frames built signal by signal with cantools, decoded with numpy."""
    rng = np.random.default_rng(3)
    message = p.load_dbc().get_message_by_name("SampleBlock")
    expected = rng.integers(-32768, 32768, size=(5, 30))
    payloads = []
    for sequence, row in enumerate(expected):
        signals = {"Sequence": 65533 + sequence, "ChannelId": 7, "SampleCount": 30}
        signals["Sequence"] %= 65536
        signals.update({f"Sample{k:02d}": int(v) for k, v in enumerate(row)})
        payloads.append(message.encode(signals))
    fast = p.decode_sample_blocks(b"".join(payloads))
    assert fast["sequence"].tolist() == [65533, 65534, 65535, 0, 1]
    assert (fast["samples"] == expected).all()
    assert (fast["channel_id"] == 7).all()


def test_control_frames_round_trip_through_cantools() -> None:
    header = p.RecordHeader(
        record_id=4_000_000_000,
        protocol_version=1,
        channel_count=3,
        pulses_per_rev=60,
        sample_rate_hz=97_656.25,
        start_time_us=1_795_251_046_635_552,
        tach_channel_id=2,
        tach_shaft="gear",
        metadata_bytes=321,
    )
    assert p.RecordHeader.from_signals(p.decode(p.RECORD_START_ID, header.encode())) == header
    info = p.ChannelDescription(9, 2, "tachometer_pulse_times", "tach (shaft 1) µ", "m/s²", 1e-4, -0.25)
    assert p.ChannelDescription.from_signals(p.decode(p.CHANNEL_INFO_ID, info.encode())) == info
    stop = p.RecordStopInfo(9, 123_456, 17, 130, 3_703_680, aborted=True)
    assert p.RecordStopInfo.from_signals(p.decode(p.RECORD_STOP_ID, stop.encode())) == stop


def test_channel_name_longer_than_32_bytes_is_refused() -> None:
    info = p.ChannelDescription(1, 0, "accelerometer", "x" * 33, "", 1.0, 0.0)
    with pytest.raises(ValueError, match="33 bytes"):
        info.encode()


def test_metadata_text_splits_into_56_byte_chunks() -> None:
    metadata = {"label": "day 12 ✓", "operator": "A. Person", "note": "x" * 100}
    length, payloads = p.encode_metadata(5, metadata)
    assert len(payloads) == -(-length // 56) == 3
    decoded = [p.decode(p.RECORD_META_ID, payload) for payload in payloads]
    assert [d["ChunkIndex"] for d in decoded] == [0, 1, 2]
    assert {d["ChunkCount"] for d in decoded} == {3}
    text = b"".join(p.meta_chunk_text(d) for d in decoded)[:length]
    import json

    assert json.loads(text) == metadata


def test_tach_frames_carry_edge_index_revolution_and_ns_ticks() -> None:
    ticks = np.array([0, 1, 2**40, 2**48 - 1, 5, 6, 7, 8, 9, 10], dtype=np.int64)
    payloads = p.encode_tach_frames(ticks, channel_id=3, pulses_per_rev=4, group_sizes=[8, 2])
    first, second = (p.load_dbc().decode_message(p.TACH_EDGES_ID, x) for x in payloads)
    assert isinstance(first, dict) and isinstance(second, dict)
    assert (first["Sequence"], first["EdgeCount"], first["FirstEdgeIndex"], first["Revolution"]) == (0, 8, 0, 0)
    assert (second["Sequence"], second["EdgeCount"], second["FirstEdgeIndex"], second["Revolution"]) == (1, 2, 8, 2)
    # cantools applies the DBC's 1e-9 s scale
    assert first["EdgeTime3"] == pytest.approx((2**48 - 1) * 1e-9, rel=1e-15)
    assert second["EdgeTime1"] == pytest.approx(10e-9)
    assert second["EdgeTime2"] == 0


@settings(max_examples=60, deadline=None)
@given(
    low=st.floats(-1e6, 1e6),
    span=st.floats(1e-6, 1e6),
    n=st.integers(2, 300),
    seed=st.integers(0, 2**31),
)
def test_quantisation_error_is_at_most_half_a_count(low: float, span: float, n: int, seed: int) -> None:
    values = low + span * np.random.default_rng(seed).random(n)
    counts, scale, offset = p.quantise(values)
    assert counts.min() >= -p.MAX_COUNT and counts.max() <= p.MAX_COUNT
    back = p.dequantise(counts, scale, offset)
    bound = 0.5 * scale * (1 + 1e-9) + 4 * np.finfo(float).eps * max(abs(low), abs(low + span))
    assert np.abs(back - values).max() <= bound
    assert scale == pytest.approx((values.max() - values.min()) / (2 * p.MAX_COUNT))


def test_quantisation_keeps_nan_and_infinities_and_constant_channels() -> None:
    values = np.array([1.0, np.nan, np.inf, -np.inf, 3.0])
    counts, scale, offset = p.quantise(values)
    back = p.dequantise(counts, scale, offset)
    assert np.isnan(back[1]) and back[2] == np.inf and back[3] == -np.inf
    assert back[[0, 4]] == pytest.approx([1.0, 3.0], abs=scale / 2)
    counts, scale, offset = p.quantise(np.full(10, 2.5))
    assert (p.dequantise(counts, scale, offset) == 2.5).all()
