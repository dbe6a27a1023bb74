"""Write simulated records in the formats the ingest readers expect.

- WAV: float32 (``scipy.io.wavfile.write``), channels in the given order, the record's rate.
- HDF5: one 1-D float64 dataset per channel at the file root, named by the channel, and a
  root attribute ``sample_rate_hz``.
- TDMS: group ``"data"``, one channel per name, channel property ``wf_increment`` = 1/rate.

The format follows the file extension: ``.wav``, ``.h5``/``.hdf5``, ``.tdms``.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

RECORD_FORMATS = {".wav": "wav", ".h5": "hdf5", ".hdf5": "hdf5", ".tdms": "tdms"}


class RecordWriteError(ValueError):
    """Unknown output format or channels that cannot be written together."""


def record_format(path: str | Path) -> str:
    suffix = Path(path).suffix.lower()
    try:
        return RECORD_FORMATS[suffix]
    except KeyError:
        known = ", ".join(sorted(RECORD_FORMATS))
        raise RecordWriteError(f"{path}: unknown record format {suffix!r} (use {known})") from None


def write_record(
    path: str | Path, channels: Mapping[str, np.ndarray], sample_rate_hz: float
) -> Path:
    """Write ``channels`` (name → 1-D samples, in order) to ``path``; the format follows the suffix."""
    path = Path(path)
    kind = record_format(path)
    lengths = {np.asarray(v).shape for v in channels.values()}
    if len(lengths) != 1 or len(next(iter(lengths))) != 1:
        raise RecordWriteError(f"{path}: channels must be 1-D and of equal length")
    path.parent.mkdir(parents=True, exist_ok=True)
    if kind == "wav":
        from scipy.io import wavfile

        if abs(sample_rate_hz - round(sample_rate_hz)) > 1e-9:
            raise RecordWriteError(f"{path}: WAV needs an integer sample rate")
        data = np.stack([np.asarray(v, dtype=np.float32) for v in channels.values()], axis=1)
        wavfile.write(path, round(sample_rate_hz), data)
    elif kind == "hdf5":
        import h5py

        with h5py.File(path, "w") as f:
            f.attrs["sample_rate_hz"] = float(sample_rate_hz)
            for name, values in channels.items():
                f.create_dataset(name, data=np.asarray(values, dtype=np.float64))
    else:
        from nptdms import ChannelObject, TdmsWriter

        with TdmsWriter(str(path)) as writer:
            objects = [
                ChannelObject(
                    "data",
                    name,
                    np.asarray(values, dtype=np.float64),
                    properties={"wf_increment": 1.0 / sample_rate_hz},
                )
                for name, values in channels.items()
            ]
            writer.write_segment(objects)
    return path
