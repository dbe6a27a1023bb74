"""MAT reader: v5 round trip with scipy.io.savemat (plain and compressed), v7.3 with h5py in
MATLAB's layout, bad input, and the real wind-turbine file (pulse-time tachometer)."""

from __future__ import annotations

import struct
from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.io

from gearwatch.floor.errors import RecordFormatError
from ingest.sources import read_record
from tests.ingest.roundtrip import RoundTripBase, make_campaign

WINDTURBINE = Path(__file__).resolve().parents[3] / "shared/data/real/windturbine-hss"


class TestMatV5RoundTrip(RoundTripBase):
    suffix = ".mat"
    atol = 0.0
    rtol = 0.0

    def write(self, path: Path, channels: dict[str, np.ndarray], sample_rate_hz: float | None) -> None:
        variables: dict[str, np.ndarray] = {k: v.reshape(-1, 1) for k, v in channels.items()}
        if sample_rate_hz is not None:
            variables["fs"] = np.array([[sample_rate_hz]])
        scipy.io.savemat(path, variables)


class TestMatV5CompressedRoundTrip(TestMatV5RoundTrip):
    decompressed_bytes_per_sample = 8
    def write(self, path: Path, channels: dict[str, np.ndarray], sample_rate_hz: float | None) -> None:
        variables: dict[str, np.ndarray] = dict(channels)  # row vectors this time
        if sample_rate_hz is not None:
            variables["sample_rate_hz"] = np.array(sample_rate_hz)
        scipy.io.savemat(path, variables, do_compression=True)


def write_mat73(path: Path, variables: dict[str, np.ndarray], *, chunked: bool = False) -> None:
    """A MAT v7.3 file as MATLAB lays it out: HDF5 after a 512-byte text block, arrays
    transposed (a MATLAB N×1 column is an HDF5 1×N dataset), ``MATLAB_class`` attributes."""
    with h5py.File(path, "w", userblock_size=512) as file:
        for name, values in variables.items():
            matrix = np.atleast_2d(values)  # MATLAB has no 1-D arrays
            options = {"chunks": True, "compression": "gzip"} if chunked else {}
            dataset = file.create_dataset(name, data=matrix, **options)
            dataset.attrs["MATLAB_class"] = np.bytes_("double" if values.dtype == np.float64 else "single")
    header = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Sat Nov 21 09:00:00 2026 HDF5 schema 1.00 ."
    with open(path, "r+b") as stream:
        stream.write(header.ljust(116, b" ") + b"\0" * 8 + struct.pack("<H", 0x0200) + b"IM")


class TestMatV73RoundTrip(RoundTripBase):
    suffix = ".mat"
    header_offset = 512
    memory_mapped = True
    atol = 0.0
    rtol = 0.0

    def write(self, path: Path, channels: dict[str, np.ndarray], sample_rate_hz: float | None) -> None:
        variables = dict(channels)
        if sample_rate_hz is not None:
            variables["fs"] = np.array(sample_rate_hz)
        write_mat73(path, variables)


class TestMatV73ChunkedRoundTrip(TestMatV73RoundTrip):
    decompressed_bytes_per_sample = 4
    memory_mapped = False

    def write(self, path: Path, channels: dict[str, np.ndarray], sample_rate_hz: float | None) -> None:
        variables = {k: v.astype(np.float32) for k, v in channels.items()}
        if sample_rate_hz is not None:
            variables["sample_rate_hz"] = np.array(sample_rate_hz)
        write_mat73(path, variables, chunked=True)

    atol = 1e-5
    rtol = 1e-6


def campaign(tmp_path: Path, names: tuple[str, ...] = ("acc1", "tach")):
    return make_campaign(tmp_path, names, sample_rate_hz=10.0)


def test_v5_truncated_after_the_declared_variables_is_still_refused(tmp_path: Path) -> None:
    path = tmp_path / "cut.mat"
    scipy.io.savemat(path, {"acc1": np.ones(100), "tach": np.zeros(100), "notes": np.zeros(5000)})
    content = path.read_bytes()
    path.write_bytes(content[: len(content) - 1000])  # only the unused 'notes' is cut
    with pytest.raises(RecordFormatError, match=r"cut\.mat.*truncated"):
        read_record(path, campaign(tmp_path))


def test_v5_struct_and_text_variables_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "struct.mat"
    scipy.io.savemat(path, {"acc1": {"x": np.ones(3)}, "tach": np.zeros(3)})
    with pytest.raises(RecordFormatError, match="'acc1' is not a real numeric array"):
        read_record(path, campaign(tmp_path))
    path = tmp_path / "text.mat"
    scipy.io.savemat(path, {"acc1": "hello", "tach": np.zeros(3)})
    with pytest.raises(RecordFormatError, match="'acc1'"):
        read_record(path, campaign(tmp_path))


def test_v5_matrix_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "matrix.mat"
    scipy.io.savemat(path, {"acc1": np.ones((10, 3)), "tach": np.zeros(10)})
    with pytest.raises(RecordFormatError, match=r"shape \(10, 3\)"):
        read_record(path, campaign(tmp_path))


def test_v73_char_variable_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "char.mat"
    write_mat73(path, {"acc1": np.ones(4), "tach": np.zeros(4)})
    with h5py.File(path, "r+") as file:
        file["acc1"].attrs["MATLAB_class"] = np.bytes_("char")
    with pytest.raises(RecordFormatError, match="MATLAB class 'char'"):
        read_record(path, campaign(tmp_path))


def test_v73_missing_variable_lists_what_is_there(tmp_path: Path) -> None:
    path = tmp_path / "few.mat"
    write_mat73(path, {"vibration": np.ones(4), "tach": np.zeros(4)})
    with pytest.raises(RecordFormatError, match=r"'acc1' not found \(file has: tach, vibration\)"):
        read_record(path, campaign(tmp_path))


@pytest.mark.skipif(not WINDTURBINE.is_dir(), reason="shared real data not present")
def test_real_windturbine_file_with_pulse_time_tachometer(tmp_path: Path) -> None:
    windturbine = make_campaign(
        tmp_path, ("vibration", "tach"), sample_rate_hz=97_656.0, tach_kind="pulse_times"
    )
    record = read_record(WINDTURBINE / "data-20130311T030024Z.mat", windturbine)
    assert record.sample_rate_hz == 97_656.0
    assert record.channels["vibration"].shape == (292_968,)
    pulse_times_s = record.channels["tach"]
    assert pulse_times_s.shape == (187,)
    assert np.all(np.diff(pulse_times_s) > 0)
    pulse_rate = (pulse_times_s.size - 1) / (pulse_times_s[-1] - pulse_times_s[0])
    assert 55.0 < pulse_rate < 63.0  # README: 55.5-62.7 pulses/s
