"""Integer samples (16-bit PCM, ADC counts) cross the CAN protocol bit-exactly.

:func:`ingest.can.protocol.exact_counts` finds the counts; the emulator sends them with their
count size and offset 0; the assembler's float64 samples then equal the file reader's, bit for
bit, so the pipeline computes the same numbers from a bus as from the file.
"""

from __future__ import annotations

import uuid
from pathlib import Path

import numpy as np
import pytest
import scipy.io.wavfile
from hypothesis import given, settings
from hypothesis import strategies as st

from gearwatch.floor.campaign import (
    Campaign,
    ChannelConfig,
    RecordData,
    RigConfig,
    TachometerConfig,
)
from ingest.can import protocol as p
from ingest.can.assembler import RecordAssembler
from ingest.can.emulator import emulate, record_frames
from ingest.can.live import listen, open_bus
from ingest.sources import read_record


def pcm_samples(counts: np.ndarray) -> np.ndarray:
    """What the WAV reader returns for int16 PCM: float32 count / 32768."""
    return counts.astype(np.float32) / np.float32(32768)


def assemble_one(record: RecordData, **options: object) -> RecordData:
    assembler = RecordAssembler(source="unit")
    frames = record_frames(record, record_id=3, **options)  # type: ignore[arg-type]
    (out,) = [r for _, m in frames for r in assembler.feed(m)]
    assert out.accepted and out.record is not None, out.reason
    return out.record


def channel_scales(record: RecordData, **options: object) -> dict[str, tuple[float, float]]:
    """(scale, offset) the emulator announces per channel in ChannelInfo."""
    infos = [
        p.ChannelDescription.from_signals(p.decode(m.arbitration_id, m.data))
        for _, m in record_frames(record, record_id=3, **options)  # type: ignore[arg-type]
        if m.arbitration_id == p.CHANNEL_INFO_ID
    ]
    return {info.name: (info.scale, info.offset) for info in infos}


def test_pcm_counts_are_found_with_the_pcm_count_size() -> None:
    rng = np.random.default_rng(1)
    counts = rng.integers(-p.MAX_COUNT, p.MAX_COUNT + 1, 10_000).astype(np.int16)
    counts[:2] = [-p.MAX_COUNT, p.MAX_COUNT]
    samples = pcm_samples(counts)
    found = p.exact_counts(samples)
    assert found is not None
    assert np.array_equal(found[0], counts) and found[1] == 2.0**-15
    back = p.dequantise(found[0], found[1], 0.0)
    assert back.dtype == np.float64 and np.array_equal(back, samples.astype(np.float64))


def test_a_quiet_pcm_channel_gets_a_finer_power_of_two() -> None:
    counts = np.array([-300, 0, 5, 299], dtype=np.int16)  # a signal far below full scale
    found = p.exact_counts(pcm_samples(counts))
    assert found is not None
    assert found[1] == 2.0**-21 and found[0].tolist() == [-19200, 0, 320, 19136]
    assert np.array_equal(p.dequantise(*found, 0.0), pcm_samples(counts).astype(np.float64))


def test_samples_that_are_not_whole_counts_are_refused() -> None:
    assert p.exact_counts(np.array([0.1, 0.2, 0.3])) is None
    # Whole counts of 2**-15, but 32767 of them: beyond the finite counts (32767 means +inf).
    assert p.exact_counts(pcm_samples(np.array([0, 32767], dtype=np.int16))) is None
    # A given count size the samples are not multiples of.
    assert p.exact_counts(np.array([0.0, 1.0, 1.5]), scale=1.0) is None
    assert p.exact_counts(np.array([0.0, 40_000.0]), scale=1.0) is None  # beyond int16


def test_a_given_count_size_need_not_be_a_power_of_two() -> None:
    lsb_v = 5.0 / 32001  # an ADC whose count is not a power of two of volts
    counts = np.array([0, 0, 31999, 31999, 7, -12345], dtype=np.int16)
    volts = counts.astype(np.float64) * lsb_v
    assert p.exact_counts(volts) is None  # not multiples of a power of two
    found = p.exact_counts(volts, scale=lsb_v)
    assert found is not None and np.array_equal(found[0], counts) and found[1] == lsb_v
    assert np.array_equal(p.dequantise(*found, 0.0), volts)


def test_nan_and_infinities_keep_their_reserved_counts() -> None:
    samples = np.array([0.5, np.nan, -np.inf, np.inf, -0.25])
    found = p.exact_counts(samples)
    assert found is not None
    counts, scale = found
    assert counts[1:4].tolist() == [p.NO_VALUE_COUNT, p.NEG_INF_COUNT, p.POS_INF_COUNT]
    back = p.dequantise(counts, scale, 0.0)
    assert np.array_equal(back, samples, equal_nan=True)
    assert p.exact_counts(np.zeros(5)) is not None and p.exact_counts(np.full(3, np.nan)) is not None


@settings(max_examples=200, deadline=None)
@given(
    counts=st.lists(st.integers(-p.MAX_COUNT, p.MAX_COUNT), min_size=1, max_size=200),
    exponent=st.integers(-40, 40),
)
def test_any_power_of_two_count_size_round_trips_bit_exactly(counts: list[int],
                                                               exponent: int) -> None:
    samples = np.array(counts, dtype=np.float64) * 2.0**exponent
    found = p.exact_counts(samples)
    assert found is not None
    assert np.array_equal(p.dequantise(found[0], found[1], 0.0), samples)
    assert int(np.abs(found[0]).max()) <= p.MAX_COUNT


def pcm_record(n: int = 3_000, seed: int = 0) -> RecordData:
    """A DAQ record as the WAV reader returns it: vibration and a 0/5 V TTL tach, as PCM."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 20_000.0
    vibration = 3.0 * np.sin(2 * np.pi * 400 * t) + rng.normal(0, 0.5, n)
    ttl = np.where(np.sin(2 * np.pi * 25 * t) > 0.9, 5.0, 0.0)
    return RecordData(
        {"acc": pcm_samples(np.rint(vibration / 64 * 32768).astype(np.int16)),
         "tach": pcm_samples(np.rint(ttl / 8 * 32768).astype(np.int16))},
        sample_rate_hz=20_000.0,
    )


def test_emulator_sends_pcm_samples_losslessly() -> None:
    sent = pcm_record()
    # The smallest power of two that keeps the counts within int16: the vibration peaks near
    # 1/14 of full scale (count size 2**-18), the 5 V tach at 5/8 of it (2**-15).
    assert channel_scales(sent, tach_channel="tach") == {
        "acc": (2.0**-18, 0.0), "tach": (2.0**-15, 0.0)
    }
    got = assemble_one(sent, tach_channel="tach")
    for name, samples in sent.channels.items():
        assert got.channels[name].dtype == np.float64
        assert np.array_equal(got.channels[name], samples.astype(np.float64)), name


def test_emulator_given_count_sizes_are_used_or_refused() -> None:
    lsb_v = 5.0 / 32001  # a 0/5 V TTL tachometer on an ADC whose count is not dyadic
    ttl = np.where(np.arange(600) % 100 < 10, 31999, 0) * lsb_v
    record = RecordData({"tach": ttl}, sample_rate_hz=1000.0)
    assert channel_scales(record, count_scales={"tach": lsb_v}) == {"tach": (lsb_v, 0.0)}
    assert np.array_equal(assemble_one(record, count_scales={"tach": lsb_v}).channels["tach"], ttl)
    # Not given: not a power-of-two multiple, so quantised over the range (lossy, documented).
    high = 31999 * lsb_v
    assert channel_scales(record)["tach"] == (high / (2 * p.MAX_COUNT), high / 2)
    with pytest.raises(ValueError, match="not whole multiples of the count size"):
        record_frames(record, record_id=1, count_scales={"tach": 1e-3 * np.pi})


def test_non_integer_waveforms_are_still_quantised_over_their_range() -> None:
    values = np.linspace(-1.0, 1.0, 301) + 1e-3  # no power-of-two count size fits
    record = RecordData({"acc": values}, sample_rate_hz=1000.0)
    scale, offset = channel_scales(record)["acc"]
    assert scale == pytest.approx(2.0 / (2 * p.MAX_COUNT)) and offset == pytest.approx(1e-3)
    error = np.abs(assemble_one(record).channels["acc"] - values).max()
    assert 0 < error <= scale / 2 * (1 + 1e-9)


def test_a_pcm_wav_file_over_the_virtual_bus_equals_the_file_read(tmp_path: Path) -> None:
    """The file as read by the WAV reader and the record assembled from the bus are equal."""
    record = pcm_record(4_000, seed=3)
    pcm = np.column_stack([np.rint(record.channels[n].astype(np.float64) * 32768)
                           for n in ("acc", "tach")]).astype(np.int16)
    path = tmp_path / "r.wav"
    scipy.io.wavfile.write(path, 20_000, pcm)
    campaign = Campaign(
        id="c", description="", rig=RigConfig(id="r"), sample_rate_hz=None,
        tachometer=TachometerConfig(channel="tach", kind="pulses"),
        channels=(ChannelConfig("acc", "accelerometer"), ChannelConfig("tach", "tachometer")),
    )
    from_file = read_record(path, campaign)
    channel = f"exact-{uuid.uuid4().hex}"
    sender, receiver = open_bus("virtual", channel), open_bus("virtual", channel)
    try:
        emulate(sender, from_file, speed=0, tach_channel="tach")
        import threading

        got: list[object] = []
        listen(receiver, got.append, stop_event=threading.Event(), max_records=1,
               idle_timeout_s=5.0)
    finally:
        sender.shutdown()
        receiver.shutdown()
    (assembled,) = got
    assert assembled.accepted and assembled.record is not None  # type: ignore[attr-defined]
    for name in ("acc", "tach"):
        bus_samples = assembled.record.channels[name]  # type: ignore[attr-defined]
        assert np.array_equal(bus_samples, from_file.channels[name].astype(np.float64)), name
