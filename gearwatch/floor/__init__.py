"""The floor: what every other room of gearwatch stands on, importing nothing of the project.

* :mod:`gearwatch.floor.errors` — the one error hierarchy (mapped to HTTP codes by the service);
* :mod:`gearwatch.floor.results` — analysis parameters and per-record result types;
* :mod:`gearwatch.floor.campaign` — campaign configuration types and :class:`RecordData`;
* :mod:`gearwatch.floor.settings` — the ``GEARWATCH_*`` settings of the service, CLI and workers;
* :mod:`gearwatch.floor.defaults` — the defaults shared by several rooms, each defined once;
* :mod:`gearwatch.floor.version` — the code version written into every provenance record.

Modules here import only the standard library, numpy and pydantic (settings) and each other;
``tests/test_architecture.py`` says so.
"""
