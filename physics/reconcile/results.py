"""What a reconciliation takes (:class:`MeasuredRecord`, :class:`ReconcileOptions`) and returns
(:class:`ReconciliationResult`, whose :meth:`~ReconciliationResult.to_json` is the issue-6 JSON
contract), and the honesty guard that names its status."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gearwatch.floor.defaults import RECONCILE_MAX_FINDINGS, SAMPLES_PER_MESH
from physics.config import GearPairModel
from physics.reconcile.catalogue import (
    DEFAULT_MECHANISMS,
    UNAVAILABLE,
)
from physics.reconcile.observables import (
    HuntingSpectrum,
)

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]



@dataclass(frozen=True)
class MeasuredRecord:
    """One accelerometer signal and its pinion tachometer pulses."""

    signal: FloatArray
    sample_rate_hz: float
    pulse_times_s: FloatArray
    pulses_per_rev: int = 1


@dataclass(frozen=True)
class ReconcileOptions:
    samples_per_mesh: int = SAMPLES_PER_MESH
    max_frequency_hz: float | None = None
    """Highest frequency fitted; default 0.4 × the sampling rate."""
    mechanisms: tuple[str, ...] = DEFAULT_MECHANISMS
    """Catalogue names scanned (default: all but :data:`NOT_SCANNED_BY_DEFAULT`)."""
    max_findings: int = RECONCILE_MAX_FINDINGS
    accept_delta_bic: float = -10.0
    """A candidate is accepted when its ΔBIC (look-elsewhere included) is below this."""
    confusable_margin: float = 6.0
    """Two confusable candidates closer than this in ΔBIC are reported as unresolved."""
    fit_load: bool = True
    fit_stiffness: bool = True
    fit_damping: bool = True
    fit_modes: bool = True
    fit_tach_delay: bool = True
    """Fit a constant delay between the tach reference and the shaft angle (trigger delay):
    a linear phase exp(−2πi f τ) on every bin; ~0.1 µs is already significant at 8 kHz."""
    tach_delay_tolerance_us: float = 10.0
    load_tolerance: float = 0.2
    """Prior σ of ln(load scale); same for ``stiffness_tolerance``."""
    stiffness_tolerance: float = 0.2
    damping_tolerance: float = 0.5
    mode_frequency_tolerance: float = 0.1
    mode_damping_tolerance: float = 0.5
    max_nfev: int = 15
    reference_max_findings: int = 2
    """Findings accepted into the base from a healthy reference (its remaining residual is
    subtracted from the record as known model-form error anyway)."""
    fit_tolerance: float = 1e-5
    """Relative change of χ² (and of the parameters) at which a least-squares fit stops:
    0.2 in χ² at χ² ≈ dof ≈ 20 000, far below any evidence threshold. SciPy's 1e-8 kept fits
    iterating (a simulation per parameter per step) on digits nothing reads."""
    polish_rounds: int = 2
    """Extra least-squares runs when a fit stops on ``max_nfev`` and χ² still drops > 1 %."""
    sensor_index: int = 0
    pool_half_width_bins: int = 10
    min_excess_share: float = 0.05
    forward_oversampling: int | None = None
    """Integrator steps per output sample of the forward simulations (None: the model's); a
    coarser step is faster and its model-form error is absorbed by the calibration."""
    anchor_gains: bool | None = None
    """Gaussian prior of the configured mode gains (relative σ ``gain_tolerance``). None: only
    for a sensor off the line of action, whose signal is ∝ friction (or support coupling)
    times the gain: the two are not separable from the data, the configuration's gain is."""
    gain_tolerance: float = 0.3
    declare_line_misfit: bool = True
    """Measure the base's relative misfit on its own mesh lines (the mesh model's form error on
    a foreign recording) and add it to those lines' variance before any mechanism is scanned
    (:mod:`physics.reconcile.discrepancy`); 0 on a record the model fits to its noise."""
    friction_on_line_of_action: bool = False
    """Scan ``sliding_friction`` on a line-of-action sensor too. Off by default: there friction
    shows only as mesh-harmonic content, which also absorbs model-form error (controls with a
    finer-step, perturbed truth scored it at ΔBIC −4 … +9, p ≈ 1e-3, too near the threshold)."""


GEAR_TOOTH_FRAME = (
    "a gear finding's 'tooth' is the configuration's numbering (gear tooth 1 meets pinion tooth 1"
    " at the simulator's mesh origin); 'tooth_in_record' is the same tooth in the record's frame:"
    " gear tooth 1 is the one pinion tooth 1 meets first after the record's first revolution mark"
)


@dataclass
class Finding:
    mechanism: str
    wheel: str | None
    tooth: int | None
    parameters: dict[str, float]
    ci95: dict[str, list[float]]
    evidence: dict[str, float]
    chi2_dof_after: float
    order: int | None = None
    model_form: str | None = None
    """Set when this finding leads a defect whose shape the catalogue does not capture."""

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "mechanism": self.mechanism,
            "wheel": self.wheel,
            "tooth": self.tooth,
            "parameters": {k: _round(v) for k, v in self.parameters.items()},
            "ci95": {k: [_round(a), _round(b)] for k, (a, b) in self.ci95.items()},
            "evidence": {k: _round(v) for k, v in self.evidence.items()},
            "chi2_dof_after": _round(self.chi2_dof_after),
        }
        if self.order is not None:
            out["order"] = self.order
        if self.model_form is not None:
            out["model_form"] = self.model_form
        return out


@dataclass
class ReconciliationResult:
    status: str
    baseline: dict[str, Any]
    mismatches: list[dict[str, Any]]
    findings: list[Finding]
    unresolved: list[dict[str, Any]]
    final: dict[str, Any]
    updated_model: GearPairModel
    calibrated_base_model: GearPairModel
    spectrum: HuntingSpectrum
    target: ComplexArray
    weights_variance: FloatArray
    base_prediction: ComplexArray
    final_prediction: ComplexArray
    candidates_scored: list[dict[str, Any]] = field(default_factory=list)
    timings_s: dict[str, float] = field(default_factory=dict)
    simulations: int = 0
    catalogue_unavailable: dict[str, str] = field(default_factory=lambda: dict(UNAVAILABLE))
    reference: dict[str, Any] | None = None
    not_scanned: dict[str, str] = field(default_factory=dict)
    """Fitted plug-ins this run did not try, and why."""
    model_form: dict[str, Any] = field(default_factory=dict)
    """Defects whose shape the catalogue does not capture (compensating findings), how the
    intervals account for model-form error, and what this sensor cannot separate."""

    def gear_tooth_in_record(self, tooth: int) -> int | None:
        """A gear tooth of the configuration's numbering in the record's own frame.

        The configuration numbers gear teeth from its mesh origin (pinion tooth 1 on gear tooth
        1), and its forward simulations reach the record's first revolution mark after
        :func:`physics.simulator.warmup_revolutions` pinion revolutions ``m``, which depends on
        the speed: there pinion tooth 1 meets gear tooth ``(m·Z1 mod Z2) + 1``. In the record's
        frame that tooth is gear tooth 1 — the one that meets pinion tooth 1 first after the
        record's first revolution mark, something the user can find on the rig. None when the
        warm-up is not stretched to a mark (a very slow shaft).

        Examples
        --------
        The 20/21 rig at 1000 rpm (m = 4, 4·20 ≡ 17 mod 21): configuration tooth 18 is the record's
        tooth 1, configuration tooth 1 the record's 5.

        >>> from physics.config import GearPairModel, Geometry
        >>> from physics.reconcile.results import ReconciliationResult
        >>> model = GearPairModel(geometry=Geometry(pinion_teeth=20, gear_teeth=21))
        >>> stub = ReconciliationResult.__new__(ReconciliationResult)
        >>> stub.calibrated_base_model = model
        >>> stub.spectrum = type("S", (), {"speed_rpm": 1000.0})()
        >>> stub.gear_tooth_in_record(18), stub.gear_tooth_in_record(1)
        (1, 5)
        """
        # lazily, like the rest of physics.reconcile: the simulator module loads the numba kernel
        from physics.simulator import warmup_revolutions

        model = self.calibrated_base_model
        geometry = model.geometry
        speed = float(self.spectrum.speed_rpm)
        m = warmup_revolutions(model, speed if speed > 0 else None)
        if m is None:
            return None
        return (int(tooth) - 1 - m * geometry.pinion_teeth) % geometry.gear_teeth + 1

    def to_json(self) -> dict[str, Any]:
        findings = []
        for finding in self.findings:
            entry = finding.to_json()
            if finding.wheel == "gear" and finding.tooth is not None:
                entry["tooth_in_record"] = self.gear_tooth_in_record(finding.tooth)
            findings.append(entry)
        return {
            "status": self.status,
            "baseline": self.baseline,
            "mismatches": [_clean(m) for m in self.mismatches],
            "findings": findings,
            "unresolved": self.unresolved,
            "final": self.final,
            "record": {
                "speed_rpm": _round(self.spectrum.speed_rpm),
                "hunting_periods": self.spectrum.segments,
                "pinion_teeth": self.spectrum.pinion_teeth,
                "gear_teeth": self.spectrum.gear_teeth,
                "gear_tooth_frame": GEAR_TOOTH_FRAME,
            },
            "reference": self.reference,
            "catalogue_unavailable": self.catalogue_unavailable,
            "not_scanned": self.not_scanned,
            "model_form": _json_safe(self.model_form),
            "simulations": self.simulations,
            "timings_s": {k: _round(v) for k, v in self.timings_s.items()},
        }


def _round(v: float) -> float:
    v = float(v)
    if not math.isfinite(v):
        return v
    return float(f"{v:.4g}")


def _json_safe(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    if isinstance(value, float | np.floating):
        return _round(float(value))
    if isinstance(value, np.integer):
        return int(value)
    return value


def _clean(m: dict[str, Any]) -> dict[str, Any]:
    return {k: (_round(v) if isinstance(v, float) else v) for k, v in m.items() if k != "contrast"}


def honesty_status(chi2_dof: float, dof: int, n_findings: int) -> str:
    """``explained`` only when χ²/dof is within ``1 ± 3√(2/dof)``; otherwise
    ``partly_explained`` (something was found) or ``not_explained``.

    Examples
    --------
    >>> honesty_status(1.01, 20000, 1), honesty_status(1.2, 20000, 1), honesty_status(1.2, 20000, 0)
    ('explained', 'partly_explained', 'not_explained')
    """
    if abs(chi2_dof - 1.0) <= 3.0 * math.sqrt(2.0 / dof):
        return "explained"
    return "partly_explained" if n_findings else "not_explained"
