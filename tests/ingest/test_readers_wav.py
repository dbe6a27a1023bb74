"""WAV reader: round trip with scipy.io.wavfile (float32 and int16 PCM) and bad input."""

from __future__ import annotations

import wave
from pathlib import Path

import numpy as np
import pytest
import scipy.io.wavfile

from gearwatch.floor.errors import RecordFormatError
from ingest.sources import read_record
from tests.ingest.roundtrip import RoundTripBase, is_memory_mapped, make_campaign


class TestWavFloat32RoundTrip(RoundTripBase):
    suffix = ".wav"
    rate_in_file = "always"
    channels_by_name = False
    supports_pulse_times = False
    memory_mapped = True

    def write(self, path: Path, channels: dict[str, np.ndarray], sample_rate_hz: float | None) -> None:
        assert sample_rate_hz is not None
        frames = np.column_stack(list(channels.values())).astype(np.float32)
        scipy.io.wavfile.write(path, int(sample_rate_hz), frames)

    def test_reads_a_view_of_the_file_not_a_copy(self, tmp_path: Path) -> None:
        written = self.signals()
        path = self.write_record(tmp_path, written)
        record = read_record(path, make_campaign(tmp_path, tuple(written), sample_rate_hz=None))
        acc1 = record.channels["acc1"]
        assert acc1.dtype == np.float32
        assert is_memory_mapped(acc1)
        assert record.metadata["dtype"] == "float32"


class TestWavInt16RoundTrip(TestWavFloat32RoundTrip):
    """int16 PCM comes back as float32 fractions of full scale (count / 32768)."""

    memory_mapped = False  # counts are converted to float32 per channel
    # Every int16 channel becomes float32: exactly twice the file, plus a few bytes of bookkeeping.
    max_read_peak_ratio = 2.01
    atol = 0.0
    rtol = 0.0

    def signals(self, n_samples: int | None = None) -> dict[str, np.ndarray]:
        return {name: np.round(x * 1000.0) / 32768.0 for name, x in super().signals(n_samples).items()}

    def write(self, path: Path, channels: dict[str, np.ndarray], sample_rate_hz: float | None) -> None:
        assert sample_rate_hz is not None
        frames = np.round(np.column_stack(list(channels.values())) * 32768.0).astype(np.int16)
        scipy.io.wavfile.write(path, int(sample_rate_hz), frames)

    def test_reads_a_view_of_the_file_not_a_copy(self, tmp_path: Path) -> None:
        pytest.skip("int16 samples are converted to float32")

    def test_nan_and_inf_come_back_unchanged(self, tmp_path: Path) -> None:
        pytest.skip("integer PCM cannot hold NaN or inf")


def test_channel_count_mismatch_says_wav_matches_by_order(tmp_path: Path) -> None:
    path = tmp_path / "mono.wav"
    scipy.io.wavfile.write(path, 8000, np.zeros(100, dtype=np.float32))
    campaign = make_campaign(tmp_path, ("acc1", "tach"), sample_rate_hz=None)
    with pytest.raises(RecordFormatError, match=r"1 channel\(s\).*declares 2.*order"):
        read_record(path, campaign)


def test_pulse_times_tachometer_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "two.wav"
    scipy.io.wavfile.write(path, 8000, np.zeros((100, 2), dtype=np.float32))
    campaign = make_campaign(tmp_path, ("acc1", "tach"), sample_rate_hz=None, tach_kind="pulse_times")
    with pytest.raises(RecordFormatError, match="pulse_times"):
        read_record(path, campaign)


@pytest.mark.parametrize("sample_width_bytes", [1, 2, 3, 4])
def test_integer_pcm_of_every_width_is_full_scale_float32(tmp_path: Path, sample_width_bytes: int) -> None:
    """Written with the standard library's wave module (the only writer of 8/24-bit PCM here)."""
    bits = 8 * sample_width_bytes
    full_scale = 2 ** (bits - 1)
    fractions = np.array([[0.0, -1.0], [0.5, 0.25], [-0.5, (full_scale - 1) / full_scale]])
    counts = np.round(fractions * full_scale).astype(np.int64)
    if sample_width_bytes == 1:
        stored = (counts + 128).astype(np.uint8).tobytes()  # 8-bit WAV is unsigned
    else:
        stored = b"".join(int(c).to_bytes(sample_width_bytes, "little", signed=True) for c in counts.ravel())
    path = tmp_path / f"pcm{bits}.wav"
    with wave.open(str(path), "wb") as writer:
        writer.setnchannels(2)
        writer.setsampwidth(sample_width_bytes)
        writer.setframerate(8000)
        writer.writeframes(stored)
    record = read_record(path, make_campaign(tmp_path, ("acc1", "tach"), sample_rate_hz=None))
    assert record.sample_rate_hz == 8000.0
    for column, name in enumerate(("acc1", "tach")):
        assert record.channels[name].dtype == np.float32
        np.testing.assert_allclose(record.channels[name], fractions[:, column], rtol=0, atol=1e-7)


def test_truncated_24_bit_file_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "cut24.wav"
    with wave.open(str(path), "wb") as writer:
        writer.setnchannels(2)
        writer.setsampwidth(3)
        writer.setframerate(8000)
        writer.writeframes(bytes(6 * 1000))
    content = path.read_bytes()
    path.write_bytes(content[: len(content) // 2 + 1])
    with pytest.raises(RecordFormatError, match=r"cut24\.wav"):
        read_record(path, make_campaign(tmp_path, ("acc1", "tach"), sample_rate_hz=None))
