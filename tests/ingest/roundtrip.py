"""Shared round-trip test base for every record format (files and CAN logs).

A format's test module subclasses :class:`RoundTripBase` with a ``Test`` name, sets
``suffix`` (and the capability flags below) and implements ``write`` with the
FORMAT'S OWN library (scipy.io.wavfile, h5py, nptdms.TdmsWriter, scipy.io.savemat,
numpy, csv/gzip, python-can + cantools ...)::

    class TestWavRoundTrip(RoundTripBase):
        suffix = ".wav"
        rate_in_file = "always"
        channels_by_name = False
        supports_pulse_times = False

        def write(self, path, channels, sample_rate_hz):
            scipy.io.wavfile.write(path, int(sample_rate_hz), np.column_stack(...))

The base writes known signals (two accelerometers and a 0/5 V TTL tachometer, or
pulse times), reads them back through the registry (:func:`ingest.sources.read_record`)
with a manifest built by :func:`ingest.manifest.parse_manifest`, and compares values,
sample rate and channel names. It also runs the shared bad-input tests: empty file,
file truncated to half, garbage bytes, corrupted header, missing or renamed channel,
missing sample rate; each must raise :class:`gearwatch.floor.errors.RecordFormatError`
whose message names the file (and the channel). NaN/inf samples must come back
unchanged (the pipeline rejects them). A tracemalloc test checks the memory bound.

A format that cannot do something overrides the flag or the test (with a reason)::

    def test_truncated_to_half(self, tmp_path):
        pytest.skip("why this format cannot detect it")
"""

from __future__ import annotations

import mmap
import tracemalloc
from pathlib import Path
from typing import Any, ClassVar, Literal

import numpy as np
import pytest

from gearwatch.floor.campaign import Campaign, RecordData
from gearwatch.floor.errors import RecordFormatError
from ingest.manifest import parse_manifest
from ingest.sources import read_record, reader_for

RateInFile = Literal["always", "optional", "never"]

TACH_CHANNEL = "tach"
ACCELEROMETERS = ("acc1", "acc2")


def known_signals(
    n_samples: int, sample_rate_hz: float, accelerometers: tuple[str, ...] = ACCELEROMETERS
) -> dict[str, np.ndarray]:
    """Deterministic test signals: tones plus seeded noise, and a 0/5 V TTL tach at 25 Hz."""
    time_s = np.arange(n_samples) / sample_rate_hz
    rng = np.random.default_rng(1234)
    signals: dict[str, np.ndarray] = {}
    for index, name in enumerate(accelerometers):
        tone_hz = 437.0 * (index + 1)
        signals[name] = 2.5 * np.sin(2 * np.pi * tone_hz * time_s + index) + 0.1 * rng.standard_normal(
            n_samples
        )
    shaft_phase = (25.0 * time_s) % 1.0
    signals[TACH_CHANNEL] = np.where(shaft_phase < 0.1, 5.0, 0.0)
    return signals


def is_memory_mapped(samples: np.ndarray) -> bool:
    """True when ``samples`` is a view of a memory-mapped file (no copy in memory)."""
    owner: object = samples
    while owner is not None:
        if isinstance(owner, np.memmap | mmap.mmap):
            return True
        owner = getattr(owner, "base", None)
    return False


def make_campaign(
    root: Path,
    channel_names: tuple[str, ...],
    *,
    sample_rate_hz: float | None,
    tach_kind: str = "pulses",
    tach_channel: str = TACH_CHANNEL,
) -> Campaign:
    """A campaign with the given channels (``tach_channel`` as tachometer, others accelerometers)."""
    data: dict[str, Any] = {
        "campaign": {"id": "roundtrip", "description": "round-trip test"},
        "rig": {"id": "rig-test", "pinion_teeth": 20, "gear_teeth": 21},
        "channels": [
            {"name": name, "kind": "tachometer" if name == tach_channel else "accelerometer"}
            for name in channel_names
        ],
    }
    if tach_channel in channel_names:
        data["tachometer"] = {"channel": tach_channel, "kind": tach_kind}
    if sample_rate_hz is not None:
        data["acquisition"] = {"sample_rate_hz": sample_rate_hz}
    return parse_manifest(data, root=root)


class RoundTripBase:
    """Base of every format's round-trip test class (not collected itself: no ``Test`` prefix)."""

    suffix: ClassVar[str] = ""
    """File suffix the format registers, e.g. ``".csv.gz"``."""
    rate_in_file: ClassVar[RateInFile] = "optional"
    """``always``: the file always carries its rate (WAV); ``optional``: ``write`` stores it
    unless given None; ``never``: the manifest's rate is used (CSV)."""
    channels_by_name: ClassVar[bool] = True
    """False when channels are matched by order (WAV)."""
    supports_pulse_times: ClassVar[bool] = True
    """True when a tachometer of pulse times (own length) can be stored beside the waveforms."""
    memory_mapped: ClassVar[bool] = False
    """True when reading maps the file instead of copying the samples."""
    max_read_peak_ratio: ClassVar[float] = 2.0
    """Bound on tracemalloc peak while reading all channels, as a multiple of the record size."""
    decompressed_bytes_per_sample: ClassVar[int | None] = None
    """For compressed formats: stored bytes per sample once decompressed. The record size
    used by the memory bound is then the larger of the file and the decompressed samples."""
    rtol: ClassVar[float] = 1e-6
    atol: ClassVar[float] = 1e-5
    """Tolerance of the value comparison (float32 storage by default)."""
    header_offset: ClassVar[int] = 0
    """Where the format's own header starts (MAT v7.3: 512, after MATLAB's text block)."""
    sample_rate_hz: ClassVar[float] = 20_000.0
    n_samples: ClassVar[int] = 4_000
    memory_test_samples: ClassVar[int] = 250_000

    # --- to implement -------------------------------------------------------------------

    def write(self, path: Path, channels: dict[str, np.ndarray], sample_rate_hz: float | None) -> None:
        """Write ``channels`` (name → 1-D float64) to ``path`` with the format's own library.

        ``sample_rate_hz`` None means: do not store a rate (``rate_in_file = "optional"``).
        """
        raise NotImplementedError

    # --- helpers (overridable) ---------------------------------------------------------

    def signals(self, n_samples: int | None = None) -> dict[str, np.ndarray]:
        return known_signals(n_samples or self.n_samples, self.sample_rate_hz)

    def record_path(self, tmp_path: Path, stem: str = "record") -> Path:
        return tmp_path / f"{stem}{self.suffix}"

    def write_record(
        self,
        tmp_path: Path,
        channels: dict[str, np.ndarray] | None = None,
        *,
        store_rate: bool = True,
        stem: str = "record",
    ) -> Path:
        path = self.record_path(tmp_path, stem)
        rate = self.sample_rate_hz if (store_rate or self.rate_in_file == "always") else None
        self.write(path, channels if channels is not None else self.signals(), rate)
        assert path.is_file() and path.stat().st_size > 0, "write() produced no file"
        return path

    def campaign_for(
        self,
        tmp_path: Path,
        channel_names: tuple[str, ...],
        *,
        manifest_rate_hz: float | None = None,
        tach_kind: str = "pulses",
    ) -> Campaign:
        return make_campaign(
            tmp_path, channel_names, sample_rate_hz=manifest_rate_hz, tach_kind=tach_kind
        )

    def default_manifest_rate(self) -> float:
        # A different manifest rate proves the file's own rate wins when it has one.
        return self.sample_rate_hz if self.rate_in_file == "never" else 12_345.0

    def assert_names_file(self, error: pytest.ExceptionInfo[RecordFormatError], path: Path) -> None:
        assert path.name in str(error.value), f"message does not name the file: {error.value}"

    def read(self, path: Path, campaign: Campaign) -> RecordData:
        return read_record(path, campaign)

    # --- round trip ----------------------------------------------------------------------

    def test_registry_picks_this_format(self, tmp_path: Path) -> None:
        reader = reader_for(tmp_path / f"x{self.suffix}")
        assert self.suffix in reader.suffixes
        assert reader_for(tmp_path / f"X{self.suffix.upper()}") is reader

    def test_round_trip_values_rate_and_names(self, tmp_path: Path) -> None:
        written = self.signals()
        path = self.write_record(tmp_path, written)
        names = tuple(written)
        campaign = self.campaign_for(
            tmp_path, names, manifest_rate_hz=self.default_manifest_rate()
        )
        record = self.read(path, campaign)
        assert list(record.channels) == list(names)
        assert record.sample_rate_hz == pytest.approx(self.sample_rate_hz, rel=1e-9)
        assert record.source == str(path)
        for name, expected in written.items():
            got = record.channels[name]
            assert got.ndim == 1 and got.dtype.kind == "f", (name, got.shape, got.dtype)
            np.testing.assert_allclose(got, expected, rtol=self.rtol, atol=self.atol, err_msg=name)

    def test_manifest_order_and_subset(self, tmp_path: Path) -> None:
        if not self.channels_by_name:
            pytest.skip("channels are matched by order in this format")
        written = self.signals()
        path = self.write_record(tmp_path, written)
        # Only acc2 and the tach, declared in another order than written.
        campaign = self.campaign_for(
            tmp_path, (TACH_CHANNEL, "acc2"), manifest_rate_hz=self.default_manifest_rate()
        )
        record = self.read(path, campaign)
        assert set(record.channels) == {TACH_CHANNEL, "acc2"}
        np.testing.assert_allclose(record.channels["acc2"], written["acc2"], rtol=self.rtol, atol=self.atol)

    def test_rate_from_manifest_when_file_has_none(self, tmp_path: Path) -> None:
        if self.rate_in_file == "always":
            pytest.skip("this format always carries its own rate")
        written = self.signals()
        path = self.write_record(tmp_path, written, store_rate=False)
        campaign = self.campaign_for(tmp_path, tuple(written), manifest_rate_hz=7_777.0)
        assert self.read(path, campaign).sample_rate_hz == 7_777.0

    def test_no_rate_anywhere_is_an_error(self, tmp_path: Path) -> None:
        if self.rate_in_file == "always":
            pytest.skip("this format always carries its own rate")
        written = self.signals()
        path = self.write_record(tmp_path, written, store_rate=False)
        campaign = self.campaign_for(tmp_path, tuple(written), manifest_rate_hz=None)
        with pytest.raises(RecordFormatError, match="sample rate") as error:
            self.read(path, campaign)
        self.assert_names_file(error, path)

    def test_pulse_times_tachometer(self, tmp_path: Path) -> None:
        written = self.signals()
        written[TACH_CHANNEL] = np.arange(1, 17) / 25.0 + 1e-4  # 16 pulse times in seconds
        if not self.supports_pulse_times:
            pytest.skip("this format cannot hold a pulse-time channel of its own length")
        path = self.write_record(tmp_path, written)
        campaign = self.campaign_for(
            tmp_path, tuple(written), manifest_rate_hz=self.default_manifest_rate(),
            tach_kind="pulse_times",
        )
        record = self.read(path, campaign)
        np.testing.assert_allclose(record.channels[TACH_CHANNEL], written[TACH_CHANNEL], rtol=1e-6)
        assert record.channels["acc1"].size == self.n_samples

    def test_nan_and_inf_come_back_unchanged(self, tmp_path: Path) -> None:
        written = self.signals()
        written["acc1"][[10, 20]] = np.nan
        written["acc2"][30] = np.inf
        written["acc2"][31] = -np.inf
        path = self.write_record(tmp_path, written)
        campaign = self.campaign_for(tmp_path, tuple(written), manifest_rate_hz=self.default_manifest_rate())
        record = self.read(path, campaign)
        assert np.flatnonzero(np.isnan(record.channels["acc1"])).tolist() == [10, 20]
        assert record.channels["acc2"][30] == np.inf and record.channels["acc2"][31] == -np.inf

    # --- bad input -----------------------------------------------------------------------

    def test_missing_channel_is_named(self, tmp_path: Path) -> None:
        written = self.signals()
        path = self.write_record(tmp_path, written)
        names = (*tuple(written), "acc_missing")
        campaign = self.campaign_for(tmp_path, names, manifest_rate_hz=self.default_manifest_rate())
        with pytest.raises(RecordFormatError, match="acc_missing") as error:
            self.read(path, campaign)
        self.assert_names_file(error, path)

    def test_wrong_channel_name_is_named(self, tmp_path: Path) -> None:
        if not self.channels_by_name:
            pytest.skip("channels are matched by order in this format")
        written = self.signals()
        path = self.write_record(tmp_path, written)
        campaign = self.campaign_for(
            tmp_path, ("acc1", "accX", TACH_CHANNEL), manifest_rate_hz=self.default_manifest_rate()
        )
        with pytest.raises(RecordFormatError, match="accX") as error:
            self.read(path, campaign)
        self.assert_names_file(error, path)

    def test_missing_tach_channel_is_named(self, tmp_path: Path) -> None:
        written = self.signals()
        del written[TACH_CHANNEL]
        path = self.write_record(tmp_path, written)
        campaign = self.campaign_for(
            tmp_path, ("acc1", "acc2", TACH_CHANNEL), manifest_rate_hz=self.default_manifest_rate()
        )
        with pytest.raises(RecordFormatError) as error:
            self.read(path, campaign)
        self.assert_names_file(error, path)
        if self.channels_by_name:
            assert TACH_CHANNEL in str(error.value)

    def test_empty_file(self, tmp_path: Path) -> None:
        path = self.record_path(tmp_path)
        path.write_bytes(b"")
        campaign = self.campaign_for(tmp_path, (*ACCELEROMETERS, TACH_CHANNEL), manifest_rate_hz=20_000.0)
        with pytest.raises(RecordFormatError, match="empty") as error:
            self.read(path, campaign)
        self.assert_names_file(error, path)

    def test_truncated_to_half(self, tmp_path: Path) -> None:
        written = self.signals()
        path = self.write_record(tmp_path, written)
        content = path.read_bytes()
        path.write_bytes(content[: len(content) // 2])
        campaign = self.campaign_for(tmp_path, tuple(written), manifest_rate_hz=20_000.0)
        with pytest.raises(RecordFormatError) as error:
            self.read(path, campaign)
        self.assert_names_file(error, path)

    def test_garbage_bytes(self, tmp_path: Path) -> None:
        path = self.record_path(tmp_path)
        path.write_bytes(np.random.default_rng(7).integers(0, 256, 5000, dtype=np.uint8).tobytes())
        campaign = self.campaign_for(tmp_path, (*ACCELEROMETERS, TACH_CHANNEL), manifest_rate_hz=20_000.0)
        with pytest.raises(RecordFormatError) as error:
            self.read(path, campaign)
        self.assert_names_file(error, path)

    def test_corrupted_header(self, tmp_path: Path) -> None:
        written = self.signals()
        path = self.write_record(tmp_path, written)
        content = bytearray(path.read_bytes())
        span = min(256, len(content) // 4)
        content[self.header_offset : self.header_offset + span] = b"\xa5" * span
        path.write_bytes(bytes(content))
        campaign = self.campaign_for(tmp_path, tuple(written), manifest_rate_hz=20_000.0)
        with pytest.raises(RecordFormatError) as error:
            self.read(path, campaign)
        self.assert_names_file(error, path)

    # --- memory ----------------------------------------------------------------------------

    def test_memory_bound(self, tmp_path: Path) -> None:
        """Reading stays within ``max_read_peak_ratio`` × record size; one float64 channel within 2×.

        Memory-mapped formats must not copy the samples at all when reading.
        """
        n = self.memory_test_samples
        written = known_signals(n, self.sample_rate_hz, accelerometers=("acc1", "acc2", "acc3"))
        path = self.write_record(tmp_path, written)
        file_bytes = path.stat().st_size
        if self.decompressed_bytes_per_sample is not None:
            file_bytes = max(file_bytes, n * len(written) * self.decompressed_bytes_per_sample)
        campaign = self.campaign_for(tmp_path, tuple(written), manifest_rate_hz=self.default_manifest_rate())
        del written
        self.read(path, campaign)  # the modules a first read imports are not the read's memory
        tracemalloc.start()
        try:
            record = self.read(path, campaign)
            held_after_read, read_peak = tracemalloc.get_traced_memory()
            tracemalloc.reset_peak()
            one_channel = np.array(record.channels["acc1"], dtype=np.float64)
            _, peak = tracemalloc.get_traced_memory()
            channel_peak = peak - held_after_read
        finally:
            tracemalloc.stop()
        print(
            f"\n{type(self).__name__}: record {file_bytes / 1e6:.2f} MB, read peak "
            f"{read_peak / file_bytes:.3f}x, one float64 channel peak {channel_peak / file_bytes:.3f}x"
        )
        assert one_channel.size == n
        assert channel_peak < 2 * file_bytes
        if self.memory_mapped:
            assert read_peak < 0.1 * file_bytes, f"read copied the samples: {read_peak} B"
        assert read_peak < self.max_read_peak_ratio * file_bytes, f"read peak {read_peak} B"
