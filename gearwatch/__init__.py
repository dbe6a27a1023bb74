"""gearwatch — online condition monitoring for gearbox test rigs.

Layers (ISO 13374 in spirit):

* acquisition — :mod:`ingest` (record files, live CAN, campaign manifests);
* data manipulation — :mod:`dsp` (pure numerics: tachometer, angle resampling,
  synchronous averaging, cepstrum, MCI, classic gear metrics);
* state detection — :mod:`detection` (baselines, alarm rules);
* advisory — :mod:`service` (REST API, dashboard);
* :mod:`physics` carries the gear-pair simulator and the physics reconciliation;
* :mod:`storage` keeps raw files, results and alarms.

This package holds what ties them together: the per-record pipeline, the command
line, provenance and the error hierarchy.
"""

from gearwatch.version import __version__

__all__ = ["__version__"]
