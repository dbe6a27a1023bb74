"""Helpers shared by the record-file readers."""

from __future__ import annotations

import math
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from gearwatch.errors import RecordFormatError
from ingest.types import Campaign

__all__ = [
    "as_channel",
    "channel_not_found",
    "is_pulse_times",
    "resolve_sample_rate",
]


def is_pulse_times(campaign: Campaign, name: str) -> bool:
    """True when ``name`` is a tachometer given as pulse times (not a waveform)."""
    tach = campaign.tachometer
    return tach is not None and tach.kind == "pulse_times" and tach.channel == name


def channel_not_found(path: Path, name: str, available: Iterable[str]) -> RecordFormatError:
    known = ", ".join(sorted(available)) or "none"
    return RecordFormatError(f"{path}: channel {name!r} not found (file has: {known})")


def resolve_sample_rate(path: Path, file_rate_hz: Any, campaign: Campaign, origin: str) -> float:
    """The file's own rate when it carries one, else the manifest's, else an error.

    ``origin`` says where the file's rate was looked for, for the error message.
    """
    if file_rate_hz is not None:
        try:
            rate = float(np.asarray(file_rate_hz, dtype=np.float64).reshape(()))
        except (TypeError, ValueError):
            raise RecordFormatError(
                f"{path}: {origin} is not a single number: {file_rate_hz!r}"
            ) from None
        if not (math.isfinite(rate) and rate > 0):
            raise RecordFormatError(f"{path}: {origin} is not a positive rate: {rate!r}")
        return rate
    if campaign.sample_rate_hz is None:
        raise RecordFormatError(
            f"{path}: no sample rate: the file has none ({origin}) and the manifest has no "
            "[acquisition] sample_rate_hz"
        )
    return float(campaign.sample_rate_hz)


def as_channel(path: Path, name: str, samples: Any) -> np.ndarray:
    """A 1-D floating-point view of ``samples`` (column/row vectors are flattened).

    float32 and float64 data are returned without a copy (memory maps stay memory
    maps); integer data are converted to float32 (float64 above 16 bits), one channel
    at a time.
    """
    array = np.asarray(samples)
    if array.ndim != 1:
        non_singleton = [n for n in array.shape if n != 1]
        if len(non_singleton) > 1:
            raise RecordFormatError(
                f"{path}: channel {name!r} has shape {array.shape}, expected a 1-D vector"
            )
        array = array.reshape(-1)
    if array.dtype.kind == "f" and array.dtype.itemsize in (4, 8):
        return array
    if array.dtype.kind in "iu" and not array.dtype == np.bool_:
        target = np.float32 if array.dtype.itemsize <= 2 else np.float64
        return array.astype(target)
    if array.dtype.kind == "f":  # float16 and long double
        return array.astype(np.float64)
    raise RecordFormatError(
        f"{path}: channel {name!r} has non-numeric dtype {array.dtype}, expected numbers"
    )
