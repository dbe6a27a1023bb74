"""h5py helpers shared by the HDF5 and MAT v7.3 readers."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import h5py
import numpy as np

from gearwatch.floor.errors import RecordFormatError
from ingest.readers._common import channel_not_found, check_declared_size


def open_hdf5(path: Path, what: str) -> h5py.File:
    try:
        return h5py.File(path, "r")
    except OSError as error:
        raise RecordFormatError(f"{path}: not a readable {what} file (truncated or corrupt): {error}") from None


def find_dataset(path: Path, file: h5py.File, name: str) -> h5py.Dataset:
    """The dataset at ``name`` (a root name or a ``group/name`` path); else a unique basename match."""
    found = file.get(name)
    if found is None:
        matches: list[h5py.Dataset] = []

        def collect(object_name: str, item: Any) -> None:
            if isinstance(item, h5py.Dataset) and object_name.rsplit("/", 1)[-1] == name:
                matches.append(item)

        file.visititems(collect)
        if len(matches) > 1:
            where = ", ".join(m.name for m in matches)
            raise RecordFormatError(f"{path}: channel {name!r} is ambiguous ({where}): give its full path")
        if not matches:
            raise channel_not_found(path, name, [k for k in file if isinstance(file[k], h5py.Dataset)])
        found = matches[0]
    if not isinstance(found, h5py.Dataset):
        raise RecordFormatError(f"{path}: {name!r} is a group, not a dataset of samples")
    return found


def read_dataset(path: Path, dataset: h5py.Dataset) -> np.ndarray:
    """The dataset's values, memory-mapped when stored contiguously and uncompressed.

    Other layouts (chunked, compressed) are read whole at their stored dtype.
    """
    mapped = _map_contiguous(path, dataset)
    if mapped is not None:
        return mapped
    declared = int(dataset.size or 0) * dataset.dtype.itemsize
    # The bytes the file really holds for it (chunks never written take none).
    stored = int(dataset.id.get_storage_size())
    compressed = dataset.compression is not None or bool(getattr(dataset, "_filters", None))
    check_declared_size(path, dataset.name or "?", declared, stored, compressed=compressed)
    try:
        values: np.ndarray = dataset[()]
    except (OSError, ValueError, TypeError) as error:
        raise RecordFormatError(f"{path}: cannot read dataset {dataset.name!r}: {error}") from None
    return np.asarray(values)


def _map_contiguous(path: Path, dataset: h5py.Dataset) -> np.ndarray | None:
    dtype = dataset.dtype
    if (
        dataset.chunks is not None
        or dataset.compression is not None
        or dataset.external
        or dtype.kind not in "iuf"
        or dataset.size == 0
        or dataset.shape is None
    ):
        return None
    offset = dataset.id.get_offset()
    if offset is None:  # space not allocated (never written)
        return None
    byte_count = int(dataset.size) * dtype.itemsize
    check_declared_size(path, dataset.name or "?", byte_count, None, compressed=False)
    if offset + byte_count > path.stat().st_size:
        raise RecordFormatError(f"{path}: dataset {dataset.name!r} runs past the end of the file (truncated)")
    mapped = np.memmap(path, dtype=dtype, mode="r", offset=offset, shape=dataset.shape)
    # Confirm the mapping on a corner of each end: a wrong offset must never give wrong samples.
    ends = (
        tuple(slice(0, min(2, n)) for n in dataset.shape),
        tuple(slice(max(0, n - 2), n) for n in dataset.shape),
    )
    for corner in ends:
        if np.asarray(mapped[corner]).tobytes() != np.asarray(dataset[corner]).tobytes():
            return None
    return mapped
