"""Reconciliation: calibrate the base, locate the mismatch, explain it by forward selection.

:func:`reconcile` takes a measured hunting-period spectrum (or a raw record) and a simulator
configuration and returns a :class:`ReconciliationResult` whose :meth:`~ReconciliationResult.to_json`
is the issue-6 JSON contract.

1. **Base calibration.** Free parameters of what the configuration holds: load and mesh
   stiffness scale and mesh damping (simulator in the loop), each configured mode's
   frequency and damping (closed form through the transfer path) — all with Gaussian priors
   of the configuration's tolerance — and the mode gains (linear, solved in closed form at
   every evaluation: variable projection). ``scipy.optimize.least_squares`` on the whitened
   residual.
2. **Locate** (:mod:`physics.reconcile.localize`).
3. **Explain.** Every catalogue candidate's linearised response (its simulation at a
   reference amplitude; one-tooth mechanisms shifted to every tooth) is projected
   orthogonally to the gains and the current Jacobian, so its Δχ² is computed jointly with
   the nuisance parameters. Score ``ΔBIC = −Δχ²/s + q ln n + 2 ln N_scan`` (``s`` =
   max(1, χ²/dof): unexplained excess deflates evidence; ``N_scan`` = candidates of that
   family: look-elsewhere). The best candidate under ``accept_delta_bic`` is refitted
   non-linearly with everything else; repeat until nothing is significant. A declared
   confusable rival as close as the linearisation can tell is refitted too (the better refit
   wins; a tie names the more common mechanism and is reported unresolved). A mechanism
   without a continuous parameter (q = 0, a switch such as ``contact_loss``) is scored by its
   non-linear refit. An off-line-of-action sensor's gains are anchored to the configuration.
4. **Honesty guard.** ``explained`` only if the final χ²/dof is within ``1 ± 3√(2/dof)``.

Examples
--------
>>> from physics.config import GearPairModel, Acquisition
>>> from physics.simulator import simulate
>>> model = GearPairModel(acquisition=Acquisition(warmup_s=0.1))
>>> rec = simulate(model, seconds=3.0, seed=2)
>>> measured = MeasuredRecord(rec.channels["acc"], rec.sample_rate_hz, rec.tach_pulse_times_s, 1)
>>> result = reconcile(measured, model, options=ReconcileOptions(samples_per_mesh=32,
...                    max_frequency_hz=5000.0, mechanisms=("pinion_eccentricity",)))
>>> result.status, len(result.findings)
('explained', 0)
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import optimize, stats

from physics.config import GearPairModel, StructuralMode
from physics.reconcile.catalogue import (
    CATALOGUE,
    CONFUSABLE,
    DEFAULT_MECHANISMS,
    NOT_SCANNED_BY_DEFAULT,
    UNAVAILABLE,
    Candidate,
    Mechanism,
    ToothMechanism,
)
from physics.reconcile.forward import ForwardModel, ForwardSetup, reconciled_modes
from physics.reconcile.localize import mismatches, nonsynchronous_mismatch
from physics.reconcile.observables import (
    HuntingSpectrum,
    gear_frame_shift,
    hunting_spectrum,
    shift_revolutions,
)

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

FRAME_EVIDENCE = 10.0
"""The best gear-frame shift must beat every other by this χ² (odds > 150 : 1) to be applied."""


@dataclass(frozen=True)
class MeasuredRecord:
    """One accelerometer signal and its pinion tachometer pulses."""

    signal: FloatArray
    sample_rate_hz: float
    pulse_times_s: FloatArray
    pulses_per_rev: int = 1


@dataclass(frozen=True)
class ReconcileOptions:
    samples_per_mesh: int = 64
    max_frequency_hz: float | None = None
    """Highest frequency fitted; default 0.4 × the sampling rate."""
    mechanisms: tuple[str, ...] = DEFAULT_MECHANISMS
    """Catalogue names scanned (default: all but :data:`NOT_SCANNED_BY_DEFAULT`)."""
    max_findings: int = 4
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
    friction_on_line_of_action: bool = False
    """Scan ``sliding_friction`` on a line-of-action sensor too. Off by default: there friction
    shows only as mesh-harmonic content, which also absorbs model-form error (controls with a
    finer-step, perturbed truth scored it at ΔBIC −4 … +9, p ≈ 1e-3, too near the threshold)."""


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

    def to_json(self) -> dict[str, Any]:
        return {
            "status": self.status,
            "baseline": self.baseline,
            "mismatches": [_clean(m) for m in self.mismatches],
            "findings": [f.to_json() for f in self.findings],
            "unresolved": self.unresolved,
            "final": self.final,
            "record": {
                "speed_rpm": _round(self.spectrum.speed_rpm),
                "hunting_periods": self.spectrum.segments,
                "pinion_teeth": self.spectrum.pinion_teeth,
                "gear_teeth": self.spectrum.gear_teeth,
            },
            "reference": self.reference,
            "catalogue_unavailable": self.catalogue_unavailable,
            "not_scanned": self.not_scanned,
            "simulations": self.simulations,
            "timings_s": {k: _round(v) for k, v in self.timings_s.items()},
        }


def _round(v: float) -> float:
    v = float(v)
    if not math.isfinite(v):
        return v
    return float(f"{v:.4g}")


def _clean(m: dict[str, Any]) -> dict[str, Any]:
    return {k: (_round(v) if isinstance(v, float) else v) for k, v in m.items() if k != "contrast"}


@dataclass
class _Accepted:
    mechanism: Mechanism
    candidate: Candidate
    vector: FloatArray
    evidence: dict[str, float]


@dataclass
class _Evaluation:
    residual: FloatArray
    gains: FloatArray
    prediction: ComplexArray
    columns: ComplexArray
    model: GearPairModel
    gain_prior: FloatArray = field(default_factory=lambda: np.zeros(0))
    """Whitened departures of anchored gains from the configuration (empty: not anchored)."""


class _Fitter:
    """Parameter layout, evaluation and non-linear fit for one measured spectrum."""

    def __init__(
        self,
        spectrum: HuntingSpectrum,
        target: ComplexArray,
        variance: FloatArray,
        model: GearPairModel,
        options: ReconcileOptions,
    ) -> None:
        self.spec = spectrum
        self.target = target
        self.used = spectrum.used
        self.weight = np.zeros(variance.shape)
        self.weight[self.used] = 1.0 / np.sqrt(variance[self.used] / 2.0)
        self.options = options
        self.base_model = model
        self.setup = ForwardSetup(
            speed_rpm=spectrum.speed_rpm,
            pinion_teeth=spectrum.pinion_teeth,
            gear_teeth=spectrum.gear_teeth,
            samples_per_mesh=spectrum.samples_per_rev // spectrum.pinion_teeth,
            n_bins=spectrum.n_bins,
            sensor_index=options.sensor_index,
            oversampling=options.forward_oversampling,
        )
        self.fm = ForwardModel(self.setup)
        self.modes: list[StructuralMode] = reconciled_modes(model, self.setup)
        self.nuisance: list[tuple[str, float, float, float]] = []  # name, start, prior σ, step
        if options.fit_load:
            self.nuisance.append(("ln_load_scale", 0.0, options.load_tolerance, 0.01))
        if options.fit_stiffness:
            self.nuisance.append(("ln_stiffness_scale", 0.0, options.stiffness_tolerance, 0.01))
        if options.fit_damping:
            zeta = model.mesh.damping_ratio
            self.nuisance.append(("ln_mesh_damping", math.log(zeta), options.damping_tolerance, 0.02))
        if options.fit_tach_delay:
            self.nuisance.append(("tach_delay_us", 0.0, options.tach_delay_tolerance_us, 0.005))
        if options.fit_modes:
            for i, mode in enumerate(self.modes):
                self.nuisance.append(
                    (f"ln_f_mode{i}", math.log(mode.frequency_hz), options.mode_frequency_tolerance, 0.001)
                )
                self.nuisance.append(
                    (f"ln_zeta_mode{i}", math.log(mode.damping_ratio), options.mode_damping_tolerance, 0.02)
                )
        self.n_rows = 2 * int(self.used.sum())
        sensor = model.sensors[options.sensor_index]
        self.off_line = sensor.direction == "off_line_of_action"
        anchor = options.anchor_gains
        if anchor is None:
            anchor = self.off_line
        # (configured gain, prior σ) per configured mode when anchored.
        self.gain_prior: list[tuple[float, float]] = (
            [(m.gain_m_s2_per_n, options.gain_tolerance * abs(m.gain_m_s2_per_n)) for m in sensor.modes]
            if anchor
            else []
        )

    # ----------------------------------------------------------------- evaluation
    def theta0(self, accepted: list[_Accepted]) -> FloatArray:
        parts = [n[1] for n in self.nuisance]
        for a in accepted:
            parts.extend(a.vector.tolist())
        return np.asarray(parts, dtype=float)

    def steps(self, accepted: list[_Accepted]) -> FloatArray:
        parts = [n[3] for n in self.nuisance]
        for a in accepted:
            parts.extend(a.mechanism.steps)
        return np.asarray(parts, dtype=float)

    def bounds(self, accepted: list[_Accepted]) -> tuple[FloatArray, FloatArray]:
        # Nuisance parameters stay within four prior σ (the configuration's tolerance).
        lo = [start - 4 * sigma for _n, start, sigma, _h in self.nuisance]
        hi = [start + 4 * sigma for _n, start, sigma, _h in self.nuisance]
        for a in accepted:
            lo.extend(a.mechanism.lower_bounds())
            hi.extend(a.mechanism.upper_bounds())
        return np.asarray(lo), np.asarray(hi)

    def model_at(self, theta: FloatArray, accepted: list[_Accepted]) -> tuple[GearPairModel, list[tuple[float, float]], list[tuple[float, float]]]:
        values = dict(zip([n[0] for n in self.nuisance], theta[: len(self.nuisance)], strict=True))
        m = self.base_model
        if "ln_load_scale" in values:
            m = m.replace(
                operating=dataclasses.replace(
                    m.operating, load_torque_nm=m.operating.load_torque_nm * math.exp(values["ln_load_scale"])
                )
            )
        mesh = m.mesh
        if "ln_stiffness_scale" in values:
            mesh = dataclasses.replace(
                mesh, stiffness_per_length_n_per_m2=mesh.stiffness_per_length_n_per_m2 * math.exp(values["ln_stiffness_scale"])
            )
        if "ln_mesh_damping" in values:
            mesh = dataclasses.replace(mesh, damping_ratio=math.exp(values["ln_mesh_damping"]))
        m = m.replace(mesh=mesh)
        tuned = []
        for i, mode in enumerate(self.modes):
            f = math.exp(values[f"ln_f_mode{i}"]) if f"ln_f_mode{i}" in values else mode.frequency_hz
            z = math.exp(values[f"ln_zeta_mode{i}"]) if f"ln_zeta_mode{i}" in values else mode.damping_ratio
            tuned.append((f, z))
        extra: list[tuple[float, float]] = []
        pos = len(self.nuisance)
        for a in accepted:
            n = len(a.mechanism.steps)
            params = a.mechanism.from_vector(theta[pos : pos + n])
            pos += n
            if a.mechanism.transfer_only:
                extra.append((params["frequency_hz"], params["damping_ratio"]))
            else:
                m = a.mechanism.apply(m, a.candidate, params)
        return m, tuned, extra

    def delay_phase(self, theta: FloatArray) -> ComplexArray | float:
        names = [n[0] for n in self.nuisance]
        if "tach_delay_us" not in names:
            return 1.0
        tau_s = float(theta[names.index("tach_delay_us")]) * 1e-6
        return np.asarray(np.exp(-2j * np.pi * self.fm.frequency_hz * tau_s), dtype=np.complex128)

    def solve_gains(self, columns: ComplexArray) -> FloatArray:
        u, w = self.used, self.weight[self.used]
        a = columns[:, u] * w
        matrix = np.concatenate([a.real, a.imag], axis=1).T
        b = self.target[u] * w
        rhs = np.concatenate([b.real, b.imag])
        if self.gain_prior:
            rows = np.zeros((len(self.gain_prior), columns.shape[0]))
            for i, (_g0, sigma) in enumerate(self.gain_prior):
                rows[i, i] = 1.0 / sigma
            matrix = np.concatenate([matrix, rows])
            rhs = np.concatenate([rhs, [g0 / sigma for g0, sigma in self.gain_prior]])
        gains, *_ = np.linalg.lstsq(matrix, rhs, rcond=None)
        return np.asarray(gains, dtype=float)

    def gain_residual(self, gains: FloatArray) -> FloatArray:
        return np.asarray([(gains[i] - g0) / sigma for i, (g0, sigma) in enumerate(self.gain_prior)], dtype=float)

    def evaluate(self, theta: FloatArray, accepted: list[_Accepted]) -> _Evaluation:
        model, tuned, extra = self.model_at(theta, accepted)
        channels = self.fm.mode_channels(model)
        columns = self.fm.transfer_columns(channels, self.modes, tuned, extra)
        columns = columns * self.delay_phase(theta)
        gains = self.solve_gains(columns)
        prediction = gains @ columns
        return _Evaluation(
            self.whiten(self.target - prediction), gains, prediction, columns, model, self.gain_residual(gains)
        )

    def whiten(self, values: ComplexArray) -> FloatArray:
        u = self.used
        z = values[u] * self.weight[u]
        return np.concatenate([z.real, z.imag])

    def prior(self, theta: FloatArray) -> FloatArray:
        n = len(self.nuisance)
        start = np.array([x[1] for x in self.nuisance])
        sigma = np.array([x[2] for x in self.nuisance])
        return np.asarray((theta[:n] - start) / sigma, dtype=float)

    # ----------------------------------------------------------------- fit
    def fit(self, accepted: list[_Accepted], theta: FloatArray | None = None) -> tuple[FloatArray, FloatArray, _Evaluation]:
        x0 = self.theta0(accepted) if theta is None else theta
        lo, hi = self.bounds(accepted)
        x0 = np.clip(x0, lo + 1e-9, hi - 1e-9)
        steps = self.steps(accepted)

        def fun(x: FloatArray) -> FloatArray:
            e = self.evaluate(x, accepted)
            return np.concatenate([e.residual, e.gain_prior, self.prior(x)])

        def jac(x: FloatArray) -> FloatArray:
            f0 = fun(x)
            cols = []
            for i, h in enumerate(steps):
                xp = x.copy()
                # Step inwards at an upper bound.
                step = h if x[i] + h <= hi[i] else -h
                xp[i] += step
                cols.append((fun(xp) - f0) / step)
            return np.stack(cols, axis=1)

        result = optimize.least_squares(
            fun, x0, jac=jac, bounds=(lo, hi), method="trf", x_scale=steps * 10, max_nfev=self.options.max_nfev
        )
        # At high SNR an unfinished fit leaves a residual that the next scan would "explain"
        # with a spurious mechanism: continue while the budget ran out and χ² still drops.
        for _ in range(self.options.polish_rounds):
            if result.status != 0:
                break
            before = float(result.cost)
            result = optimize.least_squares(
                fun, result.x, jac=jac, bounds=(lo, hi), method="trf", x_scale=steps * 10,
                max_nfev=self.options.max_nfev,
            )
            if float(result.cost) > 0.99 * before:
                break
        theta_hat = np.asarray(result.x, dtype=float)
        # Data rows, then the anchored gains' prior rows (if any; they carry the information
        # on an amplitude the gain cannot absorb).
        jacobian = np.asarray(result.jac, dtype=float)[: self.n_rows + len(self.gain_prior)]
        return theta_hat, jacobian, self.evaluate(theta_hat, accepted)

    def chi2(self, evaluation: _Evaluation) -> float:
        return float(np.sum(evaluation.residual**2))

    def dof(self, evaluation: _Evaluation, accepted: list[_Accepted]) -> int:
        n_params = evaluation.gains.size + sum(len(a.mechanism.steps) for a in accepted)
        return max(1, self.n_rows - n_params)


# ----------------------------------------------------------------------------- scan


def _shift_phase(k: FloatArray, mesh_periods: int, lcm: int) -> ComplexArray:
    """Delay by ``mesh_periods`` mesh periods on the hunting grid (``lcm`` mesh periods)."""
    out: ComplexArray = np.exp(-2j * np.pi * k * mesh_periods / lcm)
    return out


def _crt_shift(tooth_offset: int, wheel: str, z1: int, z2: int) -> int | None:
    """Mesh periods that move a one-tooth effect ``tooth_offset`` teeth on ``wheel`` only."""
    if math.gcd(z1, z2) != 1:
        return None
    lcm = z1 * z2
    for m in range(lcm):
        if wheel == "pinion" and m % z1 == tooth_offset % z1 and m % z2 == 0:
            return m
        if wheel == "gear" and m % z2 == tooth_offset % z2 and m % z1 == 0:
            return m
    return None  # pragma: no cover


def _candidate_columns(
    fitter: _Fitter,
    mechanism: Mechanism,
    theta: FloatArray,
    accepted: list[_Accepted],
    evaluation: _Evaluation,
) -> list[tuple[Candidate, ComplexArray, list[float]]]:
    """(candidate, complex response columns per unit internal vector, references)."""
    model, tuned, extra = fitter.model_at(theta, accepted)
    gains = evaluation.gains
    base_pred = evaluation.prediction
    z1, z2 = fitter.spec.pinion_teeth, fitter.spec.gear_teeth
    k = np.arange(fitter.spec.n_bins, dtype=float)
    out: list[tuple[Candidate, ComplexArray, list[float]]] = []
    if mechanism.transfer_only:
        f = fitter.fm.frequency_hz
        from physics.reconcile.forward import mode_response

        ref = fitter.modes[0]
        base_force = evaluation.columns[0] / np.where(
            np.abs(mode_response(f, *tuned[0])) > 0, mode_response(f, *tuned[0]), 1.0
        )
        for cand in mechanism.candidates(model):
            assert cand.mode_frequency_hz is not None and cand.mode_damping_ratio is not None
            col = base_force * mode_response(f, cand.mode_frequency_hz, cand.mode_damping_ratio)
            out.append((cand, col[None, :], [1.0]))
        del ref
        return out

    def response(cand: Candidate) -> ComplexArray:
        cols = []
        for vec in mechanism.scan_vectors():
            m = mechanism.apply(model, cand, mechanism.from_vector(vec))
            channels = fitter.fm.mode_channels(m)
            columns = fitter.fm.transfer_columns(channels, fitter.modes, tuned, extra)
            columns = columns * fitter.delay_phase(theta)
            cols.append((gains @ columns - base_pred) / float(np.max(np.abs(vec))))
        return np.stack(cols)

    if isinstance(mechanism, ToothMechanism):
        lcm = math.lcm(z1, z2)
        first: dict[str, ComplexArray] = {}
        for cand in mechanism.candidates(model):
            assert cand.wheel is not None and cand.tooth is not None
            shift = _crt_shift(cand.tooth - 1, cand.wheel, z1, z2)
            if shift is None:
                out.append((cand, response(cand), list(mechanism.reference)))
                continue
            if cand.wheel not in first:
                first[cand.wheel] = response(dataclasses.replace(cand, tooth=1))
            out.append((cand, first[cand.wheel] * _shift_phase(k, shift, lcm), list(mechanism.reference)))
        return out
    for cand in mechanism.candidates(model):
        out.append((cand, response(cand), list(mechanism.reference)))
    return out


@dataclass
class _Score:
    candidate: Candidate
    mechanism: Mechanism
    delta_chi2: float
    delta_bic: float
    p_value: float
    coefficients: FloatArray
    n_scan: int


def _score_all(
    fitter: _Fitter,
    theta: FloatArray,
    jacobian: FloatArray,
    accepted: list[_Accepted],
    evaluation: _Evaluation,
    chi2_scale: float,
) -> list[_Score]:
    residual = evaluation.residual
    n = fitter.n_rows
    gain_cols = np.stack([fitter.whiten(c) for c in evaluation.columns], axis=1)
    basis = np.concatenate([gain_cols, jacobian[:n]], axis=1)
    # Columns that are exactly zero (a parameter without effect, e.g. every gain of an
    # off-line sensor on a frictionless base) span nothing: QR would invent a direction.
    basis = basis[:, np.any(basis != 0.0, axis=0)]
    q, _ = np.linalg.qr(basis)
    r_perp = residual - q @ (q.T @ residual)
    scores: list[_Score] = []
    taken = {(a.candidate.mechanism, a.candidate.wheel, a.candidate.tooth) for a in accepted}
    for name in fitter.options.mechanisms:
        mechanism = CATALOGUE.get(name)
        if mechanism is None:
            continue
        if mechanism.off_line_only and not (fitter.off_line or fitter.options.friction_on_line_of_action):
            continue
        if not mechanism.steps:
            scores.extend(_switched_scores(fitter, mechanism, theta, accepted, evaluation, chi2_scale))
            continue
        items = _candidate_columns(fitter, mechanism, theta, accepted, evaluation)
        n_scan = max(1, len(items))
        for cand, cols, _refs in items:
            if (cand.mechanism, cand.wheel, cand.tooth) in taken and not mechanism.transfer_only:
                if not isinstance(mechanism, ToothMechanism):
                    continue
            d = np.stack([fitter.whiten(c) for c in cols], axis=1)
            d_perp = d - q @ (q.T @ d)
            coef, *_ = np.linalg.lstsq(d_perp, r_perp, rcond=None)
            lows = mechanism.lower_bounds()
            if mechanism.transfer_only:
                pass
            elif any(lo == 0.0 and c < 0 for lo, c in zip(lows, coef, strict=False)):
                continue
            fitted = d_perp @ coef
            delta = float(fitted @ fitted)
            # A new mode: its gain (the column) plus its frequency and damping.
            n_new = cols.shape[0] + (2 if mechanism.transfer_only else 0)
            eff = delta / chi2_scale
            bic = -eff + n_new * math.log(n) + 2.0 * math.log(n_scan)
            p = min(1.0, n_scan * float(stats.chi2.sf(eff, n_new)))
            scores.append(_Score(cand, mechanism, delta, bic, p, np.asarray(coef, dtype=float), n_scan))
    scores.sort(key=lambda s: s.delta_bic)
    return scores


def _switched_scores(
    fitter: _Fitter,
    mechanism: Mechanism,
    theta: FloatArray,
    accepted: list[_Accepted],
    evaluation: _Evaluation,
    chi2_scale: float,
) -> list[_Score]:
    """Scores of a mechanism without a continuous parameter (q = 0): a switch of the model.

    Linearising is no use here: the calibration done without it may have bent the nuisances
    (e.g. the mesh damping absorbing a loss of contact) to where switching changes nothing.
    So each candidate is refitted non-linearly, nuisances restarted from the configuration
    (as at acceptance, which then reuses the cached simulations); Δχ² is the drop, q = 0.
    """
    model = fitter.model_at(theta, accepted)[0]
    candidates = mechanism.candidates(model)
    chi2_now = fitter.chi2(evaluation)
    out = []
    for cand in candidates:
        trial = [*accepted, _Accepted(mechanism, cand, np.zeros(0), {})]
        start = theta.copy()
        start[: len(fitter.nuisance)] = [x[1] for x in fitter.nuisance]
        # Where the switch changes nothing, neither at the calibration nor at the configured
        # nuisances (e.g. no tooth ever separates), there is nothing to refit: Δχ² = 0.
        change = max(
            float(np.sum(fitter.whiten(fitter.evaluate(x, trial).prediction - fitter.evaluate(x, accepted).prediction) ** 2))
            for x in (theta, start)
        )
        if change < 1e-6:
            delta = 0.0
        else:
            _theta, _jac, switched = fitter.fit(trial, start)
            delta = chi2_now - fitter.chi2(switched)
        eff = delta / chi2_scale
        bic = -eff + 2.0 * math.log(len(candidates))
        # Not nested: the p-value of one degree of freedom (conservative).
        p = min(1.0, len(candidates) * float(stats.chi2.sf(max(eff, 0.0), 1)))
        out.append(_Score(cand, mechanism, delta, bic, p, np.zeros(0), len(candidates)))
    return out


def _refit(
    fitter: _Fitter,
    score: _Score,
    accepted: list[_Accepted],
    theta: FloatArray,
    chi2_now: float,
    scale: float,
) -> tuple[float, _Accepted, list[_Accepted], FloatArray, FloatArray, _Evaluation]:
    """Non-linear refit of the base, the accepted findings and one scored candidate.

    Returns (refit ΔBIC, the new finding, the trial list, θ, Jacobian, evaluation)."""
    vector = score.coefficients.copy()
    if score.mechanism.transfer_only:
        assert score.candidate.mode_frequency_hz is not None
        assert score.candidate.mode_damping_ratio is not None
        vector = np.array(
            [math.log(score.candidate.mode_frequency_hz), math.log(score.candidate.mode_damping_ratio)]
        )
    new = _Accepted(score.mechanism, score.candidate, vector, {})
    trial = [*accepted, new]
    # Restart the nuisance parameters from the configuration: a calibration done
    # without the mechanism may have bent them towards it (e.g. the load absorbing a
    # spall).
    theta_try = np.concatenate([theta, vector])
    theta_try[: len(fitter.nuisance)] = [x[1] for x in fitter.nuisance]
    theta_new, jac_new, eval_new = fitter.fit(trial, theta_try)
    # The evidence is re-scored on the non-linear refit: a linearised gain the refit
    # does not keep is not accepted.
    n_new = len(score.mechanism.steps) + (1 if score.mechanism.transfer_only else 0)
    gain_eff = (chi2_now - fitter.chi2(eval_new)) / scale
    refit_bic = -gain_eff + n_new * math.log(fitter.n_rows) + 2.0 * math.log(score.n_scan)
    new.evidence = {
        "delta_bic": refit_bic,
        # q = 0 (a switched model, not nested): the p-value of one degree of freedom.
        "p_value": min(1.0, score.n_scan * float(stats.chi2.sf(max(gain_eff, 0.0), max(n_new, 1)))),
        "delta_chi2": chi2_now - fitter.chi2(eval_new),
        "scanned": float(score.n_scan),
        "delta_bic_scan": score.delta_bic,
    }
    return refit_bic, new, trial, theta_new, jac_new, eval_new



# ----------------------------------------------------------------------------- driver


def reconcile(
    measured: MeasuredRecord | HuntingSpectrum,
    model: GearPairModel,
    *,
    reference: MeasuredRecord | HuntingSpectrum | None = None,
    options: ReconcileOptions | None = None,
) -> ReconciliationResult:
    """Reconcile a recording with the simulator configuration ``model``.

    Parameters
    ----------
    measured
        The recording (raw signal and pinion pulses) or its :class:`HuntingSpectrum`.
    model
        The simulator configuration of the rig (the base).
    reference
        A healthy record of the same rig: its calibrated residual is treated as known
        model-form error and only the change is explained.
    options
        :class:`ReconcileOptions`.

    Returns
    -------
    ReconciliationResult
    """
    options = options or ReconcileOptions()
    t0 = time.perf_counter()
    spec = _spectrum(measured, model, options)
    target = spec.mean.copy()
    variance = spec.variance.copy()
    timings: dict[str, float] = {"observable": time.perf_counter() - t0}
    reference_json: dict[str, Any] | None = None
    ref_nonsync: dict[str, Any] | None = None
    if reference is not None:
        # The healthy reference is reconciled first; what it needs (runout, index errors,
        # modes the configuration lacks...) is normal content of this rig and goes into the
        # base, and its remaining residual is known model-form error: only the change is
        # explained.
        ref_result = reconcile(reference, model, options=options)
        model = ref_result.updated_model
        # A pinion tach leaves each record's gear frame wherever the gear was at its first
        # pulse: bring this record onto the reference's frame (whole pinion revolutions)
        # before its residual is subtracted, so gear teeth keep the reference's numbers.
        # Without gear-frame content (an ideal gear) the frame cannot be told and is left alone.
        frame_shift, frame_match, frame_evidence = gear_frame_shift(spec, ref_result.spectrum)
        frame_aligned = frame_evidence > FRAME_EVIDENCE
        spec = shift_revolutions(spec, frame_shift if frame_aligned else 0)
        target = spec.mean.copy()
        n = min(ref_result.spectrum.n_bins, spec.n_bins)
        offset = np.zeros_like(target)
        offset[:n] = (ref_result.target - ref_result.final_prediction)[:n]
        target = target - offset
        variance[:n] = variance[:n] + ref_result.spectrum.variance[:n]
        reference_json = {
            "status": ref_result.status,
            "accepted_into_base": [f.to_json() for f in ref_result.findings],
            "chi2_dof": ref_result.final["chi2_dof"],
            "gear_frame": {
                "shift_revolutions": frame_shift if frame_aligned else 0,
                "match": round(frame_match, 4),
                "evidence_delta_chi2": round(frame_evidence, 1),
                "aligned": bool(frame_aligned),
            },
        }
        ref_nonsync = nonsynchronous_mismatch(
            ref_result.spectrum.segment_spectra, ref_result.spectrum.used,
            ref_result.spectrum.bin_frequency_hz,
        )
        timings["reference"] = time.perf_counter() - t0 - timings["observable"]

    fitter = _Fitter(spec, target, variance, model, options)
    t1 = time.perf_counter()
    theta, jacobian, evaluation = fitter.fit([])
    timings["base_calibration"] = time.perf_counter() - t1
    base_eval = evaluation
    chi2_base = fitter.chi2(evaluation)
    dof_base = fitter.dof(evaluation, [])
    base_residual = target - evaluation.prediction
    freq = fitter.fm.frequency_hz
    tooth1 = model.tachometer.tooth1_pitch_angle_deg
    located = mismatches(
        base_residual,
        variance,
        spec.used,
        freq,
        pinion_teeth=spec.pinion_teeth,
        gear_teeth=spec.gear_teeth,
        samples_per_rev=spec.samples_per_rev,
        tooth1_pitch_angle_deg=tooth1,
        min_share=options.min_excess_share,
    ) if chi2_base / dof_base > 1 + 3 * math.sqrt(2 / dof_base) else []
    # Content locked to no shaft of the pair never reaches the averages (nor χ²): it is
    # looked for in the scatter between hunting periods, whatever χ² says.
    nonsync = nonsynchronous_mismatch(spec.segment_spectra, spec.used, spec.bin_frequency_hz)
    if nonsync is not None:
        if reference is not None:
            nonsync["also_in_reference"] = bool(
                ref_nonsync is not None and ref_nonsync["band_hz"] == nonsync["band_hz"]
            )
        located.append(nonsync)

    accepted: list[_Accepted] = []
    findings: list[Finding] = []
    unresolved: list[dict[str, Any]] = []
    scored_log: list[dict[str, Any]] = []
    chi2_now = chi2_base
    t2 = time.perf_counter()
    for _round_index in range(options.max_findings):
        dof_now = fitter.dof(evaluation, accepted)
        scale = max(1.0, chi2_now / dof_now)
        scores = _score_all(fitter, theta, jacobian, accepted, evaluation, scale)
        if not scores:
            break
        best = scores[0]
        scored_log.append(
            {
                "round": _round_index + 1,
                "top": [
                    {"candidate": s.candidate.label, "delta_bic": _round(s.delta_bic), "p_value": _round(s.p_value)}
                    for s in scores[:5]
                ],
            }
        )
        if best.delta_bic >= options.accept_delta_bic:
            break

        # A declared confusable rival whose linearised score is as close as the linearisation
        # can tell (absolute margin, or 1 % of a large ΔBIC) is refitted too: the non-linear
        # fits decide (e.g. a speed fluctuation and a pinion runout share their FM).
        rivals = [
            s
            for s in scores[1:]
            if frozenset({best.candidate.mechanism, s.candidate.mechanism}) in CONFUSABLE
            and s.delta_bic < options.accept_delta_bic
            and s.delta_bic - best.delta_bic < max(options.confusable_margin, 0.01 * abs(best.delta_bic))
        ][:1]
        fits = [_refit(fitter, s, accepted, theta, chi2_now, scale) for s in [best, *rivals]]
        fits.sort(key=lambda f: f[0])
        tie: tuple[float, _Accepted] | None = None
        if len(fits) > 1:
            better_eval, worse_eval = fits[0][5], fits[1][5]
            better_dof = fitter.dof(better_eval, fits[0][2])
            # The two fits against each other, on the better one's residual scale.
            versus = (fitter.chi2(worse_eval) - fitter.chi2(better_eval)) / max(
                1.0, fitter.chi2(better_eval) / better_dof
            )
            if versus < options.confusable_margin:
                # A tie: the more common mechanism of the pair is named (a runout before a
                # shaft-locked speed fluctuation), then the scan's order; both are reported.
                order = [best.candidate, *(r.candidate for r in rivals)]
                fits.sort(key=lambda f: (f[1].mechanism.tie_precedence, order.index(f[1].candidate)))
                tie = (fits[1][0], fits[1][1])
        refit_bic, new, trial, theta_new, jac_new, eval_new = fits[0]
        if refit_bic >= options.accept_delta_bic:
            break
        chi2_new = fitter.chi2(eval_new)
        dof_new = fitter.dof(eval_new, trial)
        chosen = next(s for s in scores if s.candidate == new.candidate)
        if len(fits) > 1:
            if tie is not None:
                rival_bic, rival = tie
                pair = frozenset({new.candidate.mechanism, rival.candidate.mechanism})
                unresolved.append(
                    {
                        "candidates": [new.candidate.label, rival.candidate.label],
                        "delta_bic": [_round(refit_bic), _round(rival_bic)],
                        "separate_by": CONFUSABLE[pair],
                    }
                )
        else:
            for other in scores[1:]:
                pair = frozenset({chosen.candidate.mechanism, other.candidate.mechanism})
                if pair in CONFUSABLE and other.delta_bic - chosen.delta_bic < options.confusable_margin:
                    unresolved.append(
                        {
                            "candidates": [chosen.candidate.label, other.candidate.label],
                            "delta_bic": [_round(chosen.delta_bic), _round(other.delta_bic)],
                            "separate_by": CONFUSABLE[pair],
                        }
                    )
                    break
        accepted, theta, jacobian, evaluation, chi2_now = trial, theta_new, jac_new, eval_new, chi2_new
        findings.append(_finding(fitter, accepted, theta, jacobian, evaluation, len(accepted) - 1, chi2_new / dof_new))
    timings["selection"] = time.perf_counter() - t2
    # Parameters and intervals of every finding at the final joint fit.
    final_findings = [
        dataclasses.replace(
            _finding(fitter, accepted, theta, jacobian, evaluation, i, findings[i].chi2_dof_after),
            evidence={k: v for k, v in accepted[i].evidence.items()},
        )
        for i in range(len(accepted))
    ]
    if accepted:
        fitted_model = fitter.model_at(theta, accepted)[0]
        for a, finding in zip(accepted, final_findings, strict=True):
            finding.parameters.update(a.mechanism.derived_parameters(fitted_model, spec.speed_rpm))
    dof_final = fitter.dof(evaluation, accepted)
    chi2_dof_final = chi2_now / dof_final
    tolerance = 3 * math.sqrt(2 / dof_final)
    status = honesty_status(chi2_dof_final, dof_final, len(accepted))
    within = status == "explained"
    excess_base = chi2_base - dof_base
    excess_explained = (chi2_base - chi2_now) / excess_base if excess_base > 0 else 1.0
    excess_explained = float(min(1.0, max(0.0, excess_explained)))
    final_residual = target - evaluation.prediction
    remaining = (
        mismatches(
            final_residual,
            variance,
            spec.used,
            freq,
            pinion_teeth=spec.pinion_teeth,
            gear_teeth=spec.gear_teeth,
            samples_per_rev=spec.samples_per_rev,
            tooth1_pitch_angle_deg=tooth1,
            min_share=options.min_excess_share,
        )
        if not within
        else []
    )
    signal_energy = float(np.sum(np.abs(target[spec.used]) ** 2))
    baseline = {
        "mechanisms": _configured_mechanisms(model),
        "chi2_dof": _round(chi2_base / dof_base),
        "misfit": _round(float(np.sum(np.abs(base_residual[spec.used]) ** 2)) / signal_energy),
        "dof": dof_base,
        "calibrated": _calibration_json(fitter, theta[: len(fitter.nuisance)], base_eval.gains),
    }
    final = {
        "chi2_dof": _round(chi2_dof_final),
        "chi2_dof_bounds": [_round(1 - tolerance), _round(1 + tolerance)],
        "misfit": _round(float(np.sum(np.abs(final_residual[spec.used]) ** 2)) / signal_energy),
        "excess_explained": _round(excess_explained),
        "dof": dof_final,
        "remaining": [_clean(m) for m in remaining],
    }
    updated = _updated_model(fitter, theta, accepted, evaluation.gains)
    calibrated_base = _updated_model(fitter, theta[: len(fitter.nuisance)], [], base_eval.gains)
    timings["total"] = time.perf_counter() - t0
    return ReconciliationResult(
        status=status,
        baseline=baseline,
        mismatches=located,
        findings=final_findings,
        unresolved=unresolved,
        final=final,
        updated_model=updated,
        calibrated_base_model=calibrated_base,
        spectrum=spec,
        target=target,
        weights_variance=variance,
        base_prediction=base_eval.prediction,
        final_prediction=evaluation.prediction,
        candidates_scored=scored_log,
        timings_s=timings,
        simulations=fitter.fm.simulations,
        reference=reference_json,
        not_scanned={
            name: NOT_SCANNED_BY_DEFAULT.get(name, "not requested")
            for name in CATALOGUE
            if name not in options.mechanisms
        },
    )


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


def _spectrum(
    measured: MeasuredRecord | HuntingSpectrum, model: GearPairModel, options: ReconcileOptions
) -> HuntingSpectrum:
    if isinstance(measured, HuntingSpectrum):
        return measured
    return hunting_spectrum(
        measured.signal,
        measured.sample_rate_hz,
        measured.pulse_times_s,
        measured.pulses_per_rev,
        pinion_teeth=model.geometry.pinion_teeth,
        gear_teeth=model.geometry.gear_teeth,
        samples_per_mesh=options.samples_per_mesh,
        max_frequency_hz=options.max_frequency_hz,
        pool_half_width_bins=options.pool_half_width_bins,
    )


def _configured_mechanisms(model: GearPairModel) -> list[str]:
    d = model.deviations
    out = ["ideal_geometry" if not (d.spalls or d.cracks or d.pinion_pitch_errors_um or d.gear_pitch_errors_um) else "configured_deviations"]
    if model.sensors and model.sensors[0].modes:
        out.append(f"structural_mode x{len(model.sensors[0].modes)}")
    out += [f"tooth_spall {s.wheel} {s.tooth}" for s in d.spalls]
    out += [f"tooth_crack {c.wheel} {c.tooth}" for c in d.cracks]
    if d.pinion_eccentricity_um:
        out.append("pinion_eccentricity")
    if d.gear_eccentricity_um:
        out.append("gear_eccentricity")
    if d.pinion_tip_relief_um or d.gear_tip_relief_um:
        out.append("profile_modification")
    if model.mesh.friction_coefficient:
        out.append("sliding_friction")
    if model.operating.speed_fluctuation_fraction and model.operating.speed_fluctuation_order:
        out.append("speed_fluctuation")
    if model.operating.load_fluctuation_fraction:
        out.append("load_fluctuation")
    if not model.mesh.contact_loss:
        out.append("linear_mesh (no contact loss)")
    return out


def _calibration_json(fitter: _Fitter, nuisance: FloatArray, gains: FloatArray) -> dict[str, float]:
    out = {}
    for (name, _start, _sigma, _step), value in zip(fitter.nuisance, nuisance, strict=True):
        if name.startswith("ln_"):
            out[name[3:]] = _round(math.exp(float(value)))
        else:
            out[name] = _round(float(value))
    for i, g in enumerate(gains):
        out[f"gain{i}_m_s2_per_n"] = _round(float(g))
    return out


def _finding(
    fitter: _Fitter,
    accepted: list[_Accepted],
    theta: FloatArray,
    jacobian: FloatArray,
    evaluation: _Evaluation,
    index: int,
    chi2_dof_after: float,
) -> Finding:
    a = accepted[index]
    pos = len(fitter.nuisance) + sum(len(x.mechanism.steps) for x in accepted[:index])
    n = len(a.mechanism.steps)
    vector = theta[pos : pos + n]
    params = a.mechanism.from_vector(vector)
    ci: dict[str, list[float]] = {}
    try:
        if n == 0:
            raise ValueError("no fitted parameter")
        dof = fitter.dof(evaluation, accepted)
        scale = max(1.0, fitter.chi2(evaluation) / dof)
        prior_rows = np.zeros((len(fitter.nuisance), jacobian.shape[1]))
        prior_rows[:, : len(fitter.nuisance)] = np.diag(1.0 / np.array([x[2] for x in fitter.nuisance]))
        full = np.concatenate([jacobian, prior_rows])
        cov = np.linalg.pinv(full.T @ full) * scale
        block = cov[pos : pos + n, pos : pos + n]
        rng = np.random.default_rng(0)
        draws = rng.multivariate_normal(vector, block, size=400, method="eigh")
        samples = [a.mechanism.from_vector(d) for d in draws]
        for key in params:
            values = np.array([s[key] for s in samples])
            if key.endswith("phase_deg"):
                centred = (values - params[key] + 180.0) % 360.0 - 180.0 + params[key]
                values = centred
            ci[key] = [float(np.percentile(values, 2.5)), float(np.percentile(values, 97.5))]
    except (np.linalg.LinAlgError, ValueError):
        pass
    if a.mechanism.transfer_only:
        extra_index = sum(1 for x in accepted[: index + 1] if x.mechanism.transfer_only) - 1
        params["gain_m_s2_per_n"] = float(evaluation.gains[len(fitter.modes) + extra_index])
    return Finding(
        mechanism=a.candidate.mechanism,
        wheel=a.candidate.wheel,
        tooth=a.candidate.tooth,
        parameters=params,
        ci95=ci,
        evidence=dict(a.evidence),
        chi2_dof_after=chi2_dof_after,
        order=a.candidate.order,
    )


def _updated_model(fitter: _Fitter, theta: FloatArray, accepted: list[_Accepted], gains: FloatArray) -> GearPairModel:
    """The configuration with the calibrated base and the accepted findings (for ``--write-model``)."""
    model, tuned, extra = fitter.model_at(theta, accepted)
    idx = fitter.options.sensor_index
    sensor = model.sensors[idx]
    modes = [
        StructuralMode(frequency_hz=f, damping_ratio=z, gain_m_s2_per_n=float(g))
        for (f, z), g in zip([*tuned, *extra], gains, strict=True)
    ]
    if not sensor.modes and modes:
        modes = modes[1:] if len(modes) > 1 else modes
    sensors = list(model.sensors)
    sensors[idx] = dataclasses.replace(sensor, modes=modes)
    speed = dataclasses.replace(model.operating, speed_rpm=fitter.spec.speed_rpm)
    return model.replace(sensors=sensors, operating=speed)
