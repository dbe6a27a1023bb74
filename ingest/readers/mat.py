"""MATLAB ``.mat`` records, v5 (``scipy.io.loadmat``) and v7.3 (HDF5, read with h5py).

Channels are variables, named as in the manifest; row or column vectors are both
accepted. The rate is the scalar variable ``fs`` or ``sample_rate_hz`` when present,
else the manifest's. Only the declared variables are loaded. A v5 file is first walked
element by element (tags only, no data) so that a truncated file is refused even when
the declared variables happen to sit before the cut. v7.3 variables stored contiguously
are memory-mapped; MATLAB's usual chunked, compressed layout is read one variable at a
time. Non-numeric variables (struct, cell, char, sparse, complex) are refused.
"""

from __future__ import annotations

import struct
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import scipy.io
from scipy.io.matlab import MatReadError

from gearwatch.floor.campaign import Campaign, RecordData
from gearwatch.floor.errors import RecordFormatError
from ingest.readers._common import (
    as_channel,
    channel_not_found,
    check_declared_size,
    resolve_sample_rate,
)
from ingest.readers._hdf5 import find_dataset, open_hdf5, read_dataset
from ingest.sources import declared_channel_names, register_reader

RATE_VARIABLES = ("fs", "sample_rate_hz")
_MAT5_HEADER_BYTES = 128
_MI_COMPRESSED = 15
_MATLAB_CLASS_BYTES = {
    "double": 8, "single": 4, "int8": 1, "uint8": 1, "int16": 2, "uint16": 2, "int32": 4,
    "uint32": 4, "int64": 8, "uint64": 8, "logical": 1, "char": 2,
}
_MATLAB_NUMERIC_CLASSES = {
    "double", "single", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64",
}


@register_reader
class MatReader:
    suffixes = (".mat",)

    def read(self, path: Path, campaign: Campaign) -> RecordData:
        names = declared_channel_names(campaign)
        if h5py.is_hdf5(path):
            variables, rate_name, file_rate = _read_v73(path, names)
            version = "7.3"
        else:
            variables, rate_name, file_rate = _read_v5(path, names)
            version = "5"
        channels = {name: as_channel(path, name, variables[name]) for name in names}
        origin = f"variable {rate_name!r}" if rate_name else "no 'fs' or 'sample_rate_hz' variable"
        rate_hz = resolve_sample_rate(path, file_rate, campaign, origin)
        return RecordData(
            channels=channels,
            sample_rate_hz=rate_hz,
            source=str(path),
            metadata={"format": "mat", "mat_version": version},
        )


def _read_v5(path: Path, names: tuple[str, ...]) -> tuple[dict[str, Any], str | None, Any]:
    elements = _check_v5_complete(path)
    try:
        listed = scipy.io.whosmat(path)
        available = {name for name, _shape, _cls in listed}
        wanted = [n for n in (*names, *RATE_VARIABLES) if n in available]
        _check_v5_declared_sizes(path, listed, elements, set(wanted))
        loaded = scipy.io.loadmat(path, variable_names=wanted, squeeze_me=False, mat_dtype=False)
    except (MatReadError, ValueError, OSError, EOFError, TypeError, NotImplementedError) as error:
        raise RecordFormatError(f"{path}: not a readable MAT file (truncated or corrupt): {error}") from None
    variables: dict[str, Any] = {}
    for name in names:
        if name not in loaded:
            raise channel_not_found(path, name, [n for n in available if not n.startswith("__")])
        variables[name] = _numeric_v5(path, name, loaded[name])
    rate_name = next((n for n in RATE_VARIABLES if n in loaded), None)
    file_rate = _numeric_v5(path, rate_name, loaded[rate_name]) if rate_name else None
    return variables, rate_name, file_rate


def _numeric_v5(path: Path, name: str, value: Any) -> np.ndarray:
    if not isinstance(value, np.ndarray) or value.dtype.kind not in "iuf":
        kind = getattr(value, "dtype", type(value).__name__)
        raise RecordFormatError(f"{path}: variable {name!r} is not a real numeric array ({kind})")
    return value


def _check_v5_declared_sizes(
    path: Path,
    listed: list[tuple[str, tuple[int, ...], str]],
    elements: list[tuple[int, bool]] | None,
    wanted: set[str],
) -> None:
    """Refuse a wanted variable whose declared size passes the ceiling or what its element
    stores (a compressed element expands at most :data:`MAX_EXPANSION` times), before
    ``loadmat`` decompresses it. Top-level elements and ``whosmat`` entries are in file order."""
    for index, (name, shape, matlab_class) in enumerate(listed):
        if name not in wanted:
            continue
        declared = int(np.prod(shape, dtype=np.int64)) * _MATLAB_CLASS_BYTES.get(matlab_class, 8)
        stored, compressed = (
            elements[index] if elements is not None and index < len(elements) else (None, False)
        )
        check_declared_size(path, name, declared, stored, compressed=compressed)


def _check_v5_complete(path: Path) -> list[tuple[int, bool]] | None:
    """Walk the top-level data elements of a v5 file; refuse one that runs past the end.

    Returns each variable element's (stored bytes, compressed), in file order (``None`` for
    a file without a v5 header)."""
    elements: list[tuple[int, bool]] = []
    file_bytes = path.stat().st_size
    with open(path, "rb") as stream:
        header = stream.read(_MAT5_HEADER_BYTES)
        if len(header) < _MAT5_HEADER_BYTES:
            raise RecordFormatError(f"{path}: too short for a MAT file ({file_bytes} bytes)")
        endian = {b"IM": "<", b"MI": ">"}.get(header[126:128])
        if endian is None:
            return None  # not v5 (v4 has no such header): loadmat decides
        tag_format = struct.Struct(endian + "II")
        position = _MAT5_HEADER_BYTES
        while position < file_bytes:
            stream.seek(position)
            tag = stream.read(tag_format.size)
            if len(tag) < tag_format.size:
                raise RecordFormatError(f"{path}: truncated MAT file (cut inside an element tag)")
            data_type, byte_count = tag_format.unpack(tag)
            if data_type >> 16:  # small element: data packed into the tag itself
                position += tag_format.size
                continue
            end = position + tag_format.size + byte_count
            if end > file_bytes:
                raise RecordFormatError(
                    f"{path}: truncated or corrupt MAT file (an element of {byte_count} bytes "
                    f"at offset {position} runs past the end, {file_bytes} bytes)"
                )
            elements.append((byte_count, data_type == _MI_COMPRESSED))
            position = end if data_type == _MI_COMPRESSED else end + (-end % 8)
    return elements


def _read_v73(path: Path, names: tuple[str, ...]) -> tuple[dict[str, Any], str | None, Any]:
    with open_hdf5(path, "MAT v7.3 (HDF5)") as file:
        variables = {name: _numeric_v73(path, name, find_dataset(path, file, name)) for name in names}
        rate_name = next(
            (n for n in RATE_VARIABLES if isinstance(file.get(n), h5py.Dataset)), None
        )
        file_rate = (
            np.asarray(_numeric_v73(path, rate_name, file[rate_name])) if rate_name else None
        )
    return variables, rate_name, file_rate


def _numeric_v73(path: Path, name: str, dataset: h5py.Dataset) -> np.ndarray:
    matlab_class = dataset.attrs.get("MATLAB_class")
    if isinstance(matlab_class, bytes):
        matlab_class = matlab_class.decode("ascii", "replace")
    if matlab_class is not None and matlab_class not in _MATLAB_NUMERIC_CLASSES:
        raise RecordFormatError(
            f"{path}: variable {name!r} has MATLAB class {matlab_class!r}, expected a numeric array"
        )
    if dataset.attrs.get("MATLAB_empty"):
        raise RecordFormatError(f"{path}: variable {name!r} is empty")
    if dataset.attrs.get("MATLAB_sparse") is not None:
        raise RecordFormatError(f"{path}: variable {name!r} is sparse, expected a full array")
    if dataset.dtype.kind not in "iuf":
        raise RecordFormatError(
            f"{path}: variable {name!r} is not a real numeric array ({dataset.dtype})"
        )
    # MATLAB writes arrays transposed (column-major); a vector is the same either way.
    return read_dataset(path, dataset)
