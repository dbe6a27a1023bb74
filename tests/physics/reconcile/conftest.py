"""Shared small settings: short records, a coarse angle grid and a 4 kHz band keep each
reconciliation to a few seconds while keeping every mechanism's signature in band."""

from __future__ import annotations

import dataclasses

import pytest

from physics.config import Acquisition, GearPairModel
from physics.reconcile import ReconcileOptions


@pytest.fixture(scope="session")
def base_model() -> GearPairModel:
    return GearPairModel(acquisition=Acquisition(warmup_s=0.2))


def fast_options(**changes: object) -> ReconcileOptions:
    options = ReconcileOptions(
        samples_per_mesh=32,
        max_frequency_hz=4000.0,
        max_nfev=15,
        max_findings=3,
    )
    return dataclasses.replace(options, **changes)  # type: ignore[arg-type]
