"""Gear-pair dynamic simulator and campaign generator (see ``docs/simulator.md``).

- :mod:`physics.config` — the model (one TOML file), :class:`~physics.config.GearPairModel`.
- :mod:`physics.geometry` — spur-pair geometry on the base plane.
- :mod:`physics.simulator` — :func:`~physics.simulator.simulate` (six-DOF or torsional model).
- :mod:`physics.kernel` — the compiled Newmark loop with contact loss.
- :mod:`physics.campaign` — CETIM-style campaigns in the ingest format.
- :mod:`physics.recordio` — WAV / HDF5 / TDMS record writers.
"""
