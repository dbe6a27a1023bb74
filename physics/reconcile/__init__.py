"""Physics reconciliation (issue 6): locate a simulation/recording mismatch, name and fit the
missing physics, show the fit improve. Entry point: :func:`reconcile`."""

from physics.reconcile.catalogue import (
    CATALOGUE,
    CONFUSABLE,
    MECHANISM_NAMES,
    UNAVAILABLE,
    Candidate,
)
from physics.reconcile.method import (
    Finding,
    MeasuredRecord,
    ReconcileOptions,
    ReconciliationResult,
    reconcile,
)
from physics.reconcile.observables import HuntingSpectrum, hunting_spectrum

__all__ = [
    "CATALOGUE",
    "CONFUSABLE",
    "MECHANISM_NAMES",
    "UNAVAILABLE",
    "Candidate",
    "Finding",
    "HuntingSpectrum",
    "MeasuredRecord",
    "ReconcileOptions",
    "ReconciliationResult",
    "hunting_spectrum",
    "reconcile",
]
