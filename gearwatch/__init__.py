"""gearwatch — online condition monitoring for gearbox test rigs.

Layers (ISO 13374 in spirit), drawn in ARCHITECTURE.md:

* the floor — :mod:`gearwatch.floor` (errors, result and campaign types, settings, defaults,
  version): imports nothing of the project;
* acquisition — :mod:`ingest` (record files, live CAN, campaign manifests);
* data manipulation — :mod:`dsp` (pure numerics: tachometer, angle resampling,
  synchronous averaging, cepstrum, MCI, classic gear metrics);
* state detection — :mod:`detection` (baselines, alarm rules);
* :mod:`physics` carries the gear-pair simulator and the physics reconciliation;
* :mod:`storage` keeps raw files, results and alarms;
* the use-cases — :mod:`gearwatch.usecases` (analyse a record, ingest a file, replay or watch a
  campaign, evaluate alarms, reconcile a record, create a key, write a simulated campaign);
* the doors — :mod:`gearwatch.cli` (command line), :mod:`service` (REST API, dashboard) and
  :mod:`gearwatch.worker` (Dramatiq actors): parse, call one use-case, present.
"""

from __future__ import annotations

__all__ = ["__version__"]


def __getattr__(name: str) -> str:
    """``gearwatch.__version__`` (:data:`gearwatch.floor.version.VERSION`), without importing the floor
    on ``import gearwatch``."""
    if name == "__version__":
        from gearwatch.floor.version import package_version

        return package_version()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
