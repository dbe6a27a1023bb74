"""Issue 12 item 2: a small file cannot make a reader allocate a huge array. Declared sizes
are checked against a ceiling (``GEARWATCH_MAX_CHANNEL_BYTES``) and against what the file
stores, before anything is allocated."""

from __future__ import annotations

import resource
import zipfile
from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.io

from gearwatch.floor.errors import RecordFormatError
from ingest.sources import read_record
from tests.storage.factories import campaign_config

CAMPAIGN = campaign_config()
"""Channels ``acc`` and ``tach``."""


def _peak_rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def test_never_written_chunked_hdf5_datasets_are_refused_before_allocating(
    tmp_path: Path,
) -> None:
    path = tmp_path / "empty.h5"
    with h5py.File(path, "w") as file:
        for name in ("acc", "tach"):
            file.create_dataset(name, shape=(2**28,), dtype="f8", chunks=(2**16,))
        file.attrs["sample_rate_hz"] = 20000.0
    assert path.stat().st_size < 10_000
    before = _peak_rss_mib()
    with pytest.raises(RecordFormatError, match=r"declares 2147483648 bytes"):
        read_record(path, CAMPAIGN)
    assert _peak_rss_mib() - before < 200  # 2 GiB would have been read before


def test_a_partly_written_chunked_dataset_is_refused(tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("GEARWATCH_MAX_CHANNEL_BYTES", str(1 << 40))
    path = tmp_path / "partial.h5"
    with h5py.File(path, "w") as file:
        for name in ("acc", "tach"):
            dataset = file.create_dataset(name, shape=(2**22,), dtype="f8", chunks=(2**16,))
            dataset[: 2**16] = 1.0  # one chunk of 64 written
    with pytest.raises(RecordFormatError, match="never written, truncated or forged"):
        read_record(path, CAMPAIGN)


def test_the_ceiling_refuses_a_compressed_mat_v5_before_decompressing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "bomb.mat"
    zeros = np.zeros(2**22)  # 32 MiB of float64, a few tens of kB compressed
    scipy.io.savemat(path, {"acc": zeros, "tach": zeros, "fs": 20000.0}, do_compression=True)
    assert path.stat().st_size < 200_000
    monkeypatch.setenv("GEARWATCH_MAX_CHANNEL_BYTES", str(16 << 20))
    with pytest.raises(RecordFormatError, match=r"channel 'acc' declares 33554432 bytes, more "
                                                r"than the ceiling of 16777216 bytes"):
        read_record(path, CAMPAIGN)
    monkeypatch.setenv("GEARWATCH_MAX_CHANNEL_BYTES", str(64 << 20))
    assert read_record(path, CAMPAIGN).channels["acc"].size == 2**22


def test_a_forged_npy_header_in_a_compressed_npz_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "forged.npz"
    header = {"descr": "<f8", "fortran_order": False, "shape": (2**30,)}
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name in ("acc", "tach"):
            with archive.open(f"{name}.npy", "w") as member:
                np.lib.format.write_array_header_1_0(member, header)
                member.write(b"\0" * 4096)
    with pytest.raises(RecordFormatError, match=r"member 'acc.npy' is corrupt or truncated: "
                                                r"the header declares 8589934592 bytes"):
        read_record(path, CAMPAIGN)


def test_the_ceiling_applies_to_compressed_npz(tmp_path: Path,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "big.npz"
    zeros = np.zeros(2**21)
    np.savez_compressed(path, acc=zeros, tach=zeros, sample_rate_hz=np.array(20000.0))
    monkeypatch.setenv("GEARWATCH_MAX_CHANNEL_BYTES", str(8 << 20))
    with pytest.raises(RecordFormatError, match="more than the ceiling"):
        read_record(path, CAMPAIGN)
    monkeypatch.delenv("GEARWATCH_MAX_CHANNEL_BYTES")
    record = read_record(path, CAMPAIGN)
    assert record.channels["acc"].size == 2**21 and not record.channels["acc"].any()


def test_a_gzip_bomb_csv_is_refused_at_the_ceiling(tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    import dataclasses
    import gzip

    path = tmp_path / "bomb.csv.gz"
    with gzip.open(path, "wb", compresslevel=9) as out:
        out.write(b"acc,tach\n")
        for _ in range(64):
            out.write(b"0,0\n" * (1 << 18))  # 64 MiB of text
    assert path.stat().st_size < 1_000_000
    monkeypatch.setenv("GEARWATCH_MAX_CHANNEL_BYTES", str(8 << 20))
    campaign = dataclasses.replace(CAMPAIGN, sample_rate_hz=20000.0)
    before = _peak_rss_mib()
    with pytest.raises(RecordFormatError, match="more than 8388608 bytes of CSV text"):
        read_record(path, campaign)
    assert _peak_rss_mib() - before < 200
