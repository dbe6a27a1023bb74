"""Built-in record-file readers, one module per format; importing this package registers them.

========  =====================  =====================================================
Module    Suffixes               Channel names / sample rate
========  =====================  =====================================================
wav       .wav                   order of ``[[channels]]`` / header rate
csv       .csv, .csv.gz          header names / manifest rate
npz       .npz                   array names / ``sample_rate_hz`` (0-d) or manifest
hdf5      .h5, .hdf5, .hdf       dataset names / root attribute ``sample_rate_hz``
tdms      .tdms                  channel names in any group / ``wf_increment``
mat       .mat                   variable names (v5 and v7.3) / ``fs``, ``sample_rate_hz``
========  =====================  =====================================================
"""

from __future__ import annotations

import importlib
import pkgutil

for _module in pkgutil.iter_modules(__path__):
    if not _module.name.startswith("_"):
        importlib.import_module(f"{__name__}.{_module.name}")
