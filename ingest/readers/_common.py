"""Helpers shared by the record-file readers."""

from __future__ import annotations

import math
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from gearwatch.floor.campaign import Campaign
from gearwatch.floor.errors import RecordFormatError

__all__ = [
    "MAX_EXPANSION",
    "as_channel",
    "channel_not_found",
    "check_declared_size",
    "is_pulse_times",
    "max_channel_bytes",
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


DEFAULT_MAX_CHANNEL_BYTES = 1 << 30
"""Ceiling on the size a file may declare for one channel (1 GiB: 134 M float64 samples, 22 min
at 100 kHz); ``GEARWATCH_MAX_CHANNEL_BYTES`` changes it."""
MAX_EXPANSION = 1100
"""Largest ratio of declared to stored bytes for compressed data: deflate cannot exceed about
1032:1, so a larger ratio is not compression but data that is not in the file (never-written
chunks, a forged size). Uncompressed data must be stored whole (ratio 1)."""
SMALL_BYTES = 1 << 20
"""Below this a declared size is never refused on its ratio (headers, scalars, tiny records)."""


def max_channel_bytes() -> int:
    """The ceiling for one channel's declared size, from ``GEARWATCH_MAX_CHANNEL_BYTES``."""
    text = os.environ.get("GEARWATCH_MAX_CHANNEL_BYTES", "")
    try:
        return int(text) if text.strip() else DEFAULT_MAX_CHANNEL_BYTES
    except ValueError:
        return DEFAULT_MAX_CHANNEL_BYTES


def check_declared_size(
    path: Path, name: str, declared_bytes: int, stored_bytes: int | None, *,
    compressed: bool,
) -> None:
    """Refuse a channel BEFORE allocating it when the file declares more bytes than the
    ceiling, or more than its stored bytes can hold (see :data:`MAX_EXPANSION`).

    ``stored_bytes`` is what the file really holds for the channel (``None``: unknown)."""
    ceiling = max_channel_bytes()
    if declared_bytes > ceiling:
        raise RecordFormatError(
            f"{path}: channel {name!r} declares {declared_bytes} bytes, more than the ceiling "
            f"of {ceiling} bytes (GEARWATCH_MAX_CHANNEL_BYTES)"
        )
    if stored_bytes is None or declared_bytes <= SMALL_BYTES:
        return
    expansion = MAX_EXPANSION if compressed else 1
    if declared_bytes > expansion * stored_bytes:
        raise RecordFormatError(
            f"{path}: channel {name!r} declares {declared_bytes} bytes but the file stores "
            f"{stored_bytes} bytes of it: data never written, truncated or forged"
        )
