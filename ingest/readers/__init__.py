"""Built-in record-file readers, one module per format; importing a module registers its reader.

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

:mod:`ingest.sources` imports them: only the one a file's suffix names when that is enough
(reading a WAV file does not import h5py, nptdms or scipy.io.matlab), every one otherwise.
"""
