"""NumPy ``.npz`` records: one array per channel, named as in the manifest.

Members stored uncompressed (``numpy.savez``) are memory-mapped straight out of the zip
file: nothing is copied until the pipeline touches the samples. Compressed members
(``numpy.savez_compressed``) are decompressed one channel at a time. The rate is a
scalar member ``sample_rate_hz`` (or ``fs``) when present, else the manifest's.
Object arrays (pickles) are refused.
"""

from __future__ import annotations

import struct
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from gearwatch.floor.campaign import Campaign, RecordData
from gearwatch.floor.errors import RecordFormatError
from ingest.readers._common import (
    as_channel,
    channel_not_found,
    check_declared_size,
    resolve_sample_rate,
)
from ingest.sources import declared_channel_names, register_reader

RATE_MEMBERS = ("sample_rate_hz", "fs")
_LOCAL_HEADER = struct.Struct("<4s22xHH")  # signature ... file name length, extra field length


@register_reader
class NpzReader:
    suffixes = (".npz",)

    def read(self, path: Path, campaign: Campaign) -> RecordData:
        try:
            archive = zipfile.ZipFile(path)
        except zipfile.BadZipFile as error:
            raise RecordFormatError(
                f"{path}: not a readable .npz (zip) file, truncated or corrupt: {error}"
            ) from None
        with archive:
            members = {
                info.filename.removesuffix(".npy"): info
                for info in archive.infolist()
                if info.filename.endswith(".npy")
            }
            channels: dict[str, np.ndarray] = {}
            for name in declared_channel_names(campaign):
                if name not in members:
                    raise channel_not_found(path, name, members)
                channels[name] = as_channel(path, name, _member_array(path, archive, members[name]))
            rate_member = next((m for m in RATE_MEMBERS if m in members), None)
            file_rate = (
                _member_array(path, archive, members[rate_member]) if rate_member is not None else None
            )
        rate_hz = resolve_sample_rate(
            path, file_rate, campaign, f"member {rate_member!r}" if rate_member else "no 'sample_rate_hz' member"
        )
        return RecordData(
            channels=channels, sample_rate_hz=rate_hz, source=str(path), metadata={"format": "npz"}
        )


def _member_array(path: Path, archive: zipfile.ZipFile, info: zipfile.ZipInfo) -> np.ndarray:
    name = info.filename
    try:
        if info.compress_type == zipfile.ZIP_STORED:
            return _map_stored_member(path, info)
        with archive.open(info) as member:
            version = np.lib.format.read_magic(member)
            shape, fortran_order, dtype = _read_npy_header(member, version)
            if dtype.hasobject:
                raise ValueError("object arrays are not allowed")
            declared = int(np.prod(shape, dtype=np.int64)) * dtype.itemsize
            if declared > info.file_size:
                raise ValueError(f"the header declares {declared} bytes, the member holds "
                                 f"{info.file_size}")
            check_declared_size(path, name.removesuffix(".npy"), declared, info.compress_size,
                                compressed=True)
            return _read_npy_body(member, shape, fortran_order, dtype)
    except (zipfile.BadZipFile, EOFError, OSError, ValueError) as error:
        raise RecordFormatError(f"{path}: member {name!r} is corrupt or truncated: {error}") from None


def _map_stored_member(path: Path, info: zipfile.ZipInfo) -> np.ndarray:
    """Memory-map an uncompressed ``.npy`` member in place (read-only)."""
    file_bytes = path.stat().st_size
    with open(path, "rb") as stream:
        stream.seek(info.header_offset)
        signature, name_length, extra_length = _LOCAL_HEADER.unpack(
            _read_exactly(stream, _LOCAL_HEADER.size)
        )
        if signature != b"PK\x03\x04":
            raise ValueError("bad local file header")
        data_start = info.header_offset + _LOCAL_HEADER.size + name_length + extra_length
        stream.seek(data_start)
        version = np.lib.format.read_magic(stream)
        shape, fortran_order, dtype = _read_npy_header(stream, version)
        array_offset = stream.tell()
    if dtype.hasobject:
        raise ValueError("object arrays are not allowed")
    array_bytes = int(np.prod(shape, dtype=np.int64)) * dtype.itemsize
    check_declared_size(path, info.filename.removesuffix(".npy"), array_bytes, None,
                        compressed=False)
    if array_offset - data_start + array_bytes > info.file_size or data_start + info.file_size > file_bytes:
        raise ValueError("the array data runs past the end of the member or file")
    if array_bytes == 0:
        return np.zeros(shape, dtype=dtype)
    return np.memmap(
        path, dtype=dtype, mode="r", offset=array_offset, shape=shape,
        order="F" if fortran_order else "C",
    )


def _read_npy_body(
    stream: Any, shape: tuple[int, ...], fortran_order: bool, dtype: np.dtype[Any]
) -> np.ndarray:
    """The array after its header, read in bounded blocks (a short member is an error)."""
    count = int(np.prod(shape, dtype=np.int64))
    array = np.empty(count, dtype=dtype)
    raw = array.view(np.uint8)
    block = 16 << 20
    for start in range(0, raw.size, block):
        chunk = _read_exactly(stream, min(block, raw.size - start))
        raw[start : start + len(chunk)] = np.frombuffer(chunk, dtype=np.uint8)
    if fortran_order:
        return array.reshape(shape[::-1]).transpose()
    return array.reshape(shape)


def _read_npy_header(stream: Any, version: tuple[int, int]) -> tuple[tuple[int, ...], bool, np.dtype[Any]]:
    if version == (1, 0):
        return np.lib.format.read_array_header_1_0(stream)
    if version == (2, 0):
        return np.lib.format.read_array_header_2_0(stream)
    # Version 3.0 differs from 2.0 only in allowing utf-8 field names.
    return np.lib.format._read_array_header(stream, version)  # type: ignore[attr-defined]


def _read_exactly(stream: Any, count: int) -> bytes:
    data: bytes = stream.read(count)
    if len(data) != count:
        raise ValueError("unexpected end of file")
    return data
