"""WAV records: channels in the order of the manifest's ``[[channels]]``, rate from the header.

PCM int16/int32 and IEEE float32/float64 data are memory-mapped (``scipy.io.wavfile``
with ``mmap=True``): a float channel is returned as it is stored (the simulator writes
float32 in physical units), as a strided read-only view of the file; integer PCM
(8, 16, 24, 32 bit) is converted one channel at a time to float32 fractions of full
scale, in [-1, 1) (as audio libraries do; calibrate with the channel's unit). 24-bit PCM,
which cannot be memory-mapped, is read whole.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import scipy.io.wavfile

from gearwatch.floor.campaign import Campaign, RecordData
from gearwatch.floor.errors import RecordFormatError
from ingest.readers._common import as_channel, is_pulse_times
from ingest.sources import declared_channel_names, register_reader


@register_reader
class WavReader:
    suffixes = (".wav",)

    def read(self, path: Path, campaign: Campaign) -> RecordData:
        names = declared_channel_names(campaign)
        for name in names:
            if is_pulse_times(campaign, name):
                raise RecordFormatError(
                    f"{path}: a WAV file holds waveforms only; tachometer {name!r} cannot be "
                    "kind 'pulse_times'"
                )
        rate_hz, data = _read_wav(path)
        frames = data if data.ndim == 2 else data.reshape(-1, 1)
        if frames.shape[1] != len(names):
            raise RecordFormatError(
                f"{path}: the WAV file has {frames.shape[1]} channel(s) but the manifest declares "
                f"{len(names)} in [[channels]] ({', '.join(names)}); WAV channels are matched "
                "by that order"
            )
        if frames.shape[0] == 0:
            raise RecordFormatError(f"{path}: the WAV file holds no samples")
        channels = {name: _as_float(path, name, frames[:, i]) for i, name in enumerate(names)}
        return RecordData(
            channels=channels,
            sample_rate_hz=float(rate_hz),
            source=str(path),
            metadata={"format": "wav", "dtype": str(frames.dtype)},
        )


def _as_float(path: Path, name: str, samples: np.ndarray) -> np.ndarray:
    if samples.dtype.kind not in "iu":
        return as_channel(path, name, samples)
    converted = samples.astype(np.float32)  # the only copy: scaled in place below
    if samples.dtype == np.uint8:  # 8-bit PCM is unsigned, centred on 128
        converted -= np.float32(128.0)
        converted /= np.float32(128.0)
    else:
        # scipy left-justifies 24-bit samples in int32, so one scale per container size fits.
        converted /= np.float32(2 ** (8 * samples.dtype.itemsize - 1))
    return converted


def _read_wav(path: Path) -> tuple[int, np.ndarray]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            rate_hz, data = scipy.io.wavfile.read(path, mmap=True)
        except ValueError as error:
            if "mmap length is greater than file size" in str(error):
                raise RecordFormatError(
                    f"{path}: truncated WAV file (the data chunk is shorter than its header says)"
                ) from None
            if "mmap" not in str(error):
                raise RecordFormatError(f"{path}: not a readable WAV file: {error}") from None
            # A format scipy cannot memory-map (24-bit PCM): read it whole.
            try:
                rate_hz, data = scipy.io.wavfile.read(path, mmap=False)
            except ValueError as second:
                raise RecordFormatError(f"{path}: not a readable WAV file: {second}") from None
        except EOFError:
            raise RecordFormatError(f"{path}: truncated WAV file") from None
    for warning in caught:
        message = str(warning.message)
        if "EOF" in message or "truncat" in message.lower():
            raise RecordFormatError(f"{path}: truncated WAV file ({message})")
    return int(rate_hz), data
