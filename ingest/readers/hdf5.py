"""HDF5 records: one 1-D dataset per channel (at the root, or a ``group/name`` path).

The rate is the root attribute ``sample_rate_hz`` when present, else the manifest's.
Contiguous uncompressed datasets (h5py's default layout) are memory-mapped, others are
read one channel at a time at their stored dtype (float32 stays float32).
"""

from __future__ import annotations

from pathlib import Path

from gearwatch.floor.campaign import Campaign, RecordData
from ingest.readers._common import as_channel, resolve_sample_rate
from ingest.readers._hdf5 import find_dataset, open_hdf5, read_dataset
from ingest.sources import declared_channel_names, register_reader

RATE_ATTRIBUTE = "sample_rate_hz"


@register_reader
class Hdf5Reader:
    suffixes = (".h5", ".hdf5", ".hdf")

    def read(self, path: Path, campaign: Campaign) -> RecordData:
        with open_hdf5(path, "HDF5") as file:
            channels = {
                name: as_channel(path, name, read_dataset(path, find_dataset(path, file, name)))
                for name in declared_channel_names(campaign)
            }
            file_rate = file.attrs.get(RATE_ATTRIBUTE)
        rate_hz = resolve_sample_rate(
            path, file_rate, campaign, f"root attribute {RATE_ATTRIBUTE!r}"
        )
        return RecordData(
            channels=channels, sample_rate_hz=rate_hz, source=str(path), metadata={"format": "hdf5"}
        )
