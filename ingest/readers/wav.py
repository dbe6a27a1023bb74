"""WAV records: channels in the order of the manifest's ``[[channels]]``, rate from the header.

PCM int16/int32 and IEEE float32/float64 data are memory-mapped: a float channel is returned as it is stored (the simulator writes
float32 in physical units), as a strided read-only view of the file; integer PCM
(8, 16, 24, 32 bit) is converted one channel at a time to float32 fractions of full
scale, in [-1, 1) (as audio libraries do; calibrate with the channel's unit). 24-bit PCM,
which cannot be memory-mapped, is read whole.

A plain file — a ``fmt `` chunk of one of those four formats, then the whole ``data`` chunk — is
mapped here from its header (what ``scipy.io.wavfile.read(mmap=True)`` returns, without the ~0.2 s
its import costs a short ``gearwatch analyze``); any other layout (extra chunks, extensible or
24-bit formats, RF64, a truncated file) goes through ``scipy.io.wavfile``, which also words the
errors.
"""

from __future__ import annotations

import struct
import warnings
from pathlib import Path

import numpy as np

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


_HEADER_BYTES = 4096
"""Bytes of a file's start in which :func:`_plain_wav` looks for the ``data`` chunk."""
_PLAIN_DTYPES = {(1, 16): "<i2", (1, 32): "<i4", (3, 32): "<f4", (3, 64): "<f8"}
"""(format tag, bits per sample) → sample dtype of the files :func:`_plain_wav` maps itself."""


def _plain_wav(path: Path) -> tuple[int, np.ndarray] | None:
    """Rate and memory-mapped samples of a plain WAV file, ``None`` for any other layout.

    Plain: ``RIFF``/``WAVE``, a ``fmt `` chunk (PCM 16/32 bit or IEEE float 32/64 bit, packed
    frames), then the ``data`` chunk, whole in the file, with at most ``fact``, ``LIST`` or
    ``JUNK`` chunks between (which scipy skips silently too). The array is the one
    ``scipy.io.wavfile.read(path, mmap=True)`` gives: copy-on-write, ``(frames, channels)`` for
    several channels, 1-D for one.
    """
    with open(path, "rb") as fid:
        header = fid.read(_HEADER_BYTES)
        size = fid.seek(0, 2)
    if header[:4] != b"RIFF" or header[8:16] != b"WAVE" + b"fmt " or len(header) < 36:
        return None
    fmt_size, tag, channels, rate, _, block_align, bits = struct.unpack("<IHHIIHH", header[16:36])
    dtype = _PLAIN_DTYPES.get((tag, bits))
    if dtype is None or fmt_size not in (16, 18) or channels < 1 or block_align != channels * bits // 8:
        return None
    at = 20 + fmt_size + fmt_size % 2
    while at + 8 <= len(header):
        chunk, chunk_size = header[at : at + 4], struct.unpack("<I", header[at + 4 : at + 8])[0]
        if chunk == b"data":
            start = at + 8
            if chunk_size == 0 or chunk_size % block_align or start + chunk_size > size:
                return None
            data = np.memmap(path, dtype=dtype, mode="c", offset=start,
                             shape=(chunk_size * 8 // bits,))
            return rate, (data.reshape(-1, channels) if channels > 1 else data)
        if chunk not in (b"fact", b"LIST", b"JUNK"):
            return None
        at += 8 + chunk_size + chunk_size % 2
    return None


def _read_wav(path: Path) -> tuple[int, np.ndarray]:
    plain = _plain_wav(path)
    if plain is not None:
        return plain
    import scipy.io.wavfile  # the other layouts (its import is a large part of a short command)

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
