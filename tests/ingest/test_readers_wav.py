"""WAV reader: round trip with scipy.io.wavfile (float32 and int16 PCM) and bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.io.wavfile

from gearwatch.errors import RecordFormatError
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
    """int16 PCM comes back as float32 raw counts (no rescaling)."""

    memory_mapped = False  # counts are converted to float32 per channel
    # Every int16 channel becomes float32: exactly twice the file, plus a few bytes of bookkeeping.
    max_read_peak_ratio = 2.01
    atol = 0.0
    rtol = 0.0

    def signals(self, n_samples: int | None = None) -> dict[str, np.ndarray]:
        return {name: np.round(x * 1000.0) for name, x in super().signals(n_samples).items()}

    def write(self, path: Path, channels: dict[str, np.ndarray], sample_rate_hz: float | None) -> None:
        assert sample_rate_hz is not None
        frames = np.column_stack(list(channels.values())).astype(np.int16)
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
