"""Physics reconciliation (issue 6): locate a simulation/recording mismatch, name and fit the
missing physics, show the fit improve. Entry point: :func:`reconcile`."""

from physics.reconcile.catalogue import (
    CATALOGUE,
    CONFUSABLE,
    DEFAULT_MECHANISMS,
    MECHANISM_NAMES,
    NOT_SCANNED_BY_DEFAULT,
    UNAVAILABLE,
    Candidate,
)
from physics.reconcile.method import reconcile
from physics.reconcile.observables import HuntingSpectrum, hunting_spectrum
from physics.reconcile.results import (
    Finding,
    MeasuredRecord,
    ReconcileOptions,
    ReconciliationResult,
)

__all__ = [
    "CATALOGUE",
    "CONFUSABLE",
    "DEFAULT_MECHANISMS",
    "MECHANISM_NAMES",
    "NOT_SCANNED_BY_DEFAULT",
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
