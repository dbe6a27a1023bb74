"""NPZ reader: round trip with numpy.savez (memory-mapped) and savez_compressed, bad input."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from gearwatch.floor.errors import RecordFormatError
from ingest.sources import read_record
from tests.ingest.roundtrip import RoundTripBase, is_memory_mapped, make_campaign


class TestNpzRoundTrip(RoundTripBase):
    suffix = ".npz"
    memory_mapped = True
    atol = 0.0
    rtol = 0.0

    def write(self, path: Path, channels: dict[str, np.ndarray], sample_rate_hz: float | None) -> None:
        arrays: dict[str, Any] = dict(channels)
        if sample_rate_hz is not None:
            arrays["sample_rate_hz"] = np.float64(sample_rate_hz)
        with open(path, "wb") as stream:
            np.savez(stream, **arrays)

    def test_uncompressed_members_are_memory_maps(self, tmp_path: Path) -> None:
        written = self.signals()
        path = self.write_record(tmp_path, written)
        record = read_record(path, make_campaign(tmp_path, tuple(written), sample_rate_hz=None))
        assert all(is_memory_mapped(x) for x in record.channels.values())


class TestNpzCompressedRoundTrip(TestNpzRoundTrip):
    decompressed_bytes_per_sample = 8
    memory_mapped = False

    def write(self, path: Path, channels: dict[str, np.ndarray], sample_rate_hz: float | None) -> None:
        arrays: dict[str, Any] = dict(channels)
        if sample_rate_hz is not None:
            arrays["fs"] = np.float64(sample_rate_hz)
        with open(path, "wb") as stream:
            np.savez_compressed(stream, **arrays)

    def test_uncompressed_members_are_memory_maps(self, tmp_path: Path) -> None:
        pytest.skip("compressed members are decompressed")


class TestNpzFloat32ColumnVectors(TestNpzRoundTrip):
    """float32 (N, 1) arrays, as MATLAB-minded writers produce, come back 1-D float32."""

    atol = 1e-5
    rtol = 1e-6

    def write(self, path: Path, channels: dict[str, np.ndarray], sample_rate_hz: float | None) -> None:
        arrays: dict[str, Any] = {k: v.astype(np.float32).reshape(-1, 1) for k, v in channels.items()}
        if sample_rate_hz is not None:
            arrays["sample_rate_hz"] = np.float64(sample_rate_hz)
        with open(path, "wb") as stream:
            np.savez(stream, **arrays)


def test_object_arrays_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "obj.npz"
    np.savez(path, acc1=np.array([{"a": 1}], dtype=object), tach=np.zeros(3))
    with pytest.raises(RecordFormatError, match=r"obj\.npz"):
        read_record(path, make_campaign(tmp_path, ("acc1", "tach"), sample_rate_hz=1.0))


def test_two_dimensional_channel_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "mat.npz"
    np.savez(path, acc1=np.zeros((10, 2)), tach=np.zeros(10))
    with pytest.raises(RecordFormatError, match=r"'acc1'.*shape \(10, 2\)"):
        read_record(path, make_campaign(tmp_path, ("acc1", "tach"), sample_rate_hz=1.0))


def test_unequal_lengths_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "len.npz"
    np.savez(path, acc1=np.zeros(10), tach=np.zeros(9))
    with pytest.raises(RecordFormatError, match="different lengths"):
        read_record(path, make_campaign(tmp_path, ("acc1", "tach"), sample_rate_hz=1.0))
