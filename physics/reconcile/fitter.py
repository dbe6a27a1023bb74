"""The joint fit of a reconciliation: parameter layout (calibrated base, accepted findings), one
evaluation of the simulator in the loop with the mode gains in closed form, the non-linear least
squares fit, and what is read from a fit (calibration, finding intervals, updated model)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize

from physics.config import GearPairModel, StructuralMode
from physics.reconcile.catalogue import (
    Candidate,
    Mechanism,
)
from physics.reconcile.forward import ForwardModel, ForwardSetup, reconciled_modes
from physics.reconcile.honesty import pinion_order_clusters, robust_covariance
from physics.reconcile.observables import (
    HuntingSpectrum,
)
from physics.reconcile.results import (
    ComplexArray,
    Finding,
    FloatArray,
    ReconcileOptions,
    _round,
)


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
        self.set_variance(variance)
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
        self._delay_cache: dict[float, ComplexArray] = {}
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
        tau_us = float(theta[names.index("tach_delay_us")])
        cached = self._delay_cache.get(tau_us)
        if cached is None:
            cached = np.asarray(np.exp(-2j * np.pi * self.fm.frequency_hz * tau_us * 1e-6), dtype=np.complex128)
            if len(self._delay_cache) > 64:
                self._delay_cache.clear()
            self._delay_cache[tau_us] = cached
        return cached

    def solve_gains(self, columns: ComplexArray) -> FloatArray:
        # Real gains of complex columns by the normal equations (a few columns, well scaled
        # after whitening): Re(A Aᴴ) g = Re(A bᴴ). An SVD of the stacked 2n × m matrix at every
        # evaluation cost a fifth of a reconciliation.
        u, w = self.used, self.weight[self.used]
        a = columns[:, u] * w
        b = self.target[u] * w
        matrix = np.real(a @ a.conj().T)
        rhs = np.real(a @ b.conj())
        if self.gain_prior:
            for i, (g0, sigma) in enumerate(self.gain_prior):
                matrix[i, i] += 1.0 / sigma**2
                rhs[i] += g0 / sigma**2
        scale = np.sqrt(np.maximum(np.diag(matrix), 1e-300))
        # Zero columns (an off-line sensor's gains on a frictionless base) span nothing: their
        # gains stay 0 (the minimum-norm solution), as with the stacked least squares.
        gains, *_ = np.linalg.lstsq(matrix / np.outer(scale, scale), rhs / scale, rcond=1e-12)
        return np.asarray(gains / scale, dtype=float)

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

    def set_variance(self, variance: FloatArray) -> None:
        """The per-bin variance the residual is whitened by (χ² = Σ 2|r|²/v over the used bins)."""
        self.weight = np.zeros(variance.shape)
        self.weight[self.used] = 1.0 / np.sqrt(variance[self.used] / 2.0)

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

        tol = self.options.fit_tolerance
        result = optimize.least_squares(
            fun, x0, jac=jac, bounds=(lo, hi), method="trf", x_scale=steps * 10, max_nfev=self.options.max_nfev,
            ftol=tol, xtol=tol,
        )
        # At high SNR an unfinished fit leaves a residual that the next scan would "explain"
        # with a spurious mechanism: continue while the budget ran out and χ² still drops.
        for _ in range(self.options.polish_rounds):
            if result.status != 0:
                break
            before = float(result.cost)
            result = optimize.least_squares(
                fun, result.x, jac=jac, bounds=(lo, hi), method="trf", x_scale=steps * 10,
                max_nfev=self.options.max_nfev, ftol=tol, xtol=tol,
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


def _covariance(
    fitter: _Fitter, accepted: list[_Accepted], jacobian: FloatArray, evaluation: _Evaluation, *, robust: bool
) -> FloatArray:
    """Covariance of θ at the joint fit: model-based × max(1, χ²/dof), or (``robust``) widened
    to the cluster-robust sandwich where model-form error sits on a parameter's signature."""
    dof = fitter.dof(evaluation, accepted)
    scale = max(1.0, fitter.chi2(evaluation) / dof)
    prior_rows = np.zeros((len(fitter.nuisance), jacobian.shape[1]))
    prior_rows[:, : len(fitter.nuisance)] = np.diag(1.0 / np.array([x[2] for x in fitter.nuisance]))
    data = jacobian[: fitter.n_rows]
    gain_rows = jacobian[fitter.n_rows :]
    precision = prior_rows.T @ prior_rows + gain_rows.T @ gain_rows
    # A weak prior on each finding's parameters (σ: its physical range / √12, else 20× the
    # scan's reference amplitude): a parameter the data no longer moves (a spall deeper than
    # the cavity's contact) gets an interval as wide as its range, not the zero width a
    # pseudo-inverse gives a flat direction.
    pos = len(fitter.nuisance)
    for a in accepted:
        lows, highs = a.mechanism.lower_bounds(), a.mechanism.upper_bounds()
        refs = list(a.mechanism.reference) or [1.0] * len(a.mechanism.steps)
        for i in range(len(a.mechanism.steps)):
            width = highs[i] - lows[i]
            sigma = width / math.sqrt(12.0) if math.isfinite(width) else 20.0 * abs(refs[min(i, len(refs) - 1)])
            precision[pos + i, pos + i] += 1.0 / sigma**2
        pos += len(a.mechanism.steps)
    if not robust:
        return np.asarray(np.linalg.pinv(data.T @ data + precision) * scale, dtype=float)
    clusters = pinion_order_clusters(fitter.used, fitter.spec.revs_per_hunt)
    return robust_covariance(data, evaluation.residual, precision, clusters, scale)


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
        cov = _covariance(fitter, accepted, jacobian, evaluation, robust=True)
        block = cov[pos : pos + n, pos : pos + n]
        rng = np.random.default_rng(0)
        draws = rng.multivariate_normal(vector, block, size=400, method="eigh")
        # An interval never leaves the mechanism's physical bounds (depth ≥ 0, loss < 0.95 …).
        draws = np.clip(draws, a.mechanism.lower_bounds(), a.mechanism.upper_bounds())
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
