"""Step 3 of a reconciliation, *explain*: score every catalogue candidate on the linearised
residual, refit the best non-linearly, accept it when its ΔBIC is low enough, repeat."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import stats

from physics.reconcile.catalogue import (
    CATALOGUE,
    CONFUSABLE,
    Candidate,
    Mechanism,
    ToothMechanism,
)
from physics.reconcile.fitter import _Accepted, _Evaluation, _finding, _Fitter
from physics.reconcile.path import MIN_PEAK_RATIO, mode_peak_ratio
from physics.reconcile.results import (
    ComplexArray,
    Finding,
    FloatArray,
    ReconcileOptions,
    _round,
)


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


def scanned_mechanisms(fitter: _Fitter, names: tuple[str, ...]) -> list[Mechanism]:
    """The catalogue mechanisms among ``names`` that this sensor lets a scan try (friction-only
    mechanisms need a sensor off the line of action, or the option that asks for them)."""
    out = []
    for name in names:
        mechanism = CATALOGUE.get(name)
        if mechanism is None:
            continue
        if mechanism.off_line_only and not (fitter.off_line or fitter.options.friction_on_line_of_action):
            continue
        out.append(mechanism)
    return out


def _score_all(
    fitter: _Fitter,
    theta: FloatArray,
    jacobian: FloatArray,
    accepted: list[_Accepted],
    evaluation: _Evaluation,
    chi2_scale: float,
    mechanisms: tuple[str, ...],
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
    for mechanism in scanned_mechanisms(fitter, mechanisms):
        if not mechanism.steps:
            scores.extend(_switched_scores(fitter, mechanism, theta, accepted, evaluation, chi2_scale))
            continue
        items = _candidate_columns(fitter, mechanism, theta, accepted, evaluation)
        n_scan = max(1, len(items))
        if mechanism.transfer_only:
            # A new mode only where the residual shows its peak (path.py): never a sink for
            # misfit spread over the band by a path the configuration was not built with.
            items = [it for it, ok in zip(items, _identifiable_modes(fitter, evaluation, items), strict=True) if ok]
        for cand, cols, _refs in items:
            # The same mechanism at the same place again is not a new finding: the refit already
            # moved that parameter, and a second copy only shows where the linearisation of a
            # saturated parameter (a spall deeper than its contact) is wrong — it was the
            # "spall again, 36.9 µm" companion of issue 15.
            if (cand.mechanism, cand.wheel, cand.tooth) in taken and not mechanism.transfer_only:
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


def _residual_peak_ratios(
    fitter: _Fitter, evaluation: _Evaluation, frequency_hz: FloatArray, damping_ratio: FloatArray
) -> FloatArray:
    """:func:`mode_peak_ratio` of ``evaluation``'s residual (χ² per used bin) for modes at
    ``frequency_hz`` with ``damping_ratio``."""
    half = evaluation.residual.size // 2
    residual = evaluation.residual[: 2 * half]
    chi2 = residual[:half] ** 2 + residual[half:] ** 2
    return np.asarray(mode_peak_ratio(chi2, fitter.fm.frequency_hz[fitter.used], frequency_hz, damping_ratio))


def _identifiable_modes(
    fitter: _Fitter, evaluation: _Evaluation, items: list[tuple[Candidate, ComplexArray, list[float]]]
) -> list[bool]:
    """Whether each mode candidate's frequency band holds a peak of the current residual."""
    f0 = np.array([c.mode_frequency_hz or 0.0 for c, _cols, _r in items])
    zeta = np.array([c.mode_damping_ratio or 0.0 for c, _cols, _r in items])
    return [bool(r >= MIN_PEAK_RATIO) for r in _residual_peak_ratios(fitter, evaluation, f0, zeta)]


def _refit_mode_on_a_peak(
    fitter: _Fitter, evaluation: _Evaluation, theta: FloatArray, trial: list[_Accepted]
) -> bool:
    """Whether the last accepted mode's refitted frequency and damping still frame a peak of
    ``evaluation``'s residual (the residual before the mode, :func:`mode_peak_ratio`): the scan
    checks its grid point, the refit may move it anywhere."""
    frequency_hz, damping_ratio = fitter.model_at(theta, trial)[2][-1]
    ratio = _residual_peak_ratios(fitter, evaluation, np.array([frequency_hz]), np.array([damping_ratio]))
    return bool(ratio[0] >= MIN_PEAK_RATIO)


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


@dataclass
class _Selection:
    """What forward selection ends with: the accepted findings and the joint fit."""

    accepted: list[_Accepted]
    findings: list[Finding]
    unresolved: list[dict[str, Any]]
    scored_log: list[dict[str, Any]]
    theta: FloatArray
    jacobian: FloatArray
    evaluation: _Evaluation
    chi2: float


def _select(
    fitter: _Fitter,
    theta: FloatArray,
    jacobian: FloatArray,
    evaluation: _Evaluation,
    chi2_base: float,
    options: ReconcileOptions,
) -> _Selection:
    """Forward selection from the calibrated base: at most ``options.max_findings`` rounds."""
    accepted: list[_Accepted] = []
    findings: list[Finding] = []
    unresolved: list[dict[str, Any]] = []
    scored_log: list[dict[str, Any]] = []
    chi2_now = chi2_base
    for _round_index in range(options.max_findings):
        dof_now = fitter.dof(evaluation, accepted)
        scale = max(1.0, chi2_now / dof_now)
        scores = _score_all(fitter, theta, jacobian, accepted, evaluation, scale, options.mechanisms)
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
        fits, tie = _refit_with_rivals(fitter, scores, accepted, theta, chi2_now, scale, options)
        refit_bic, new, trial, theta_new, jac_new, eval_new = fits[0]
        if new.mechanism.transfer_only and not _refit_mode_on_a_peak(fitter, evaluation, theta_new, trial):
            # The refit slid the mode off every peak of this round's residual (a sharp mode
            # beside a mesh line is a free gain on that line): a sink for misfit elsewhere, not
            # a resonance. The round goes on without modes.
            scored_log[-1]["mode_off_peak"] = new.candidate.label
            scores = [s for s in scores if not s.mechanism.transfer_only]
            if not scores or scores[0].delta_bic >= options.accept_delta_bic:
                break
            fits, tie = _refit_with_rivals(fitter, scores, accepted, theta, chi2_now, scale, options)
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
    return _Selection(accepted, findings, unresolved, scored_log, theta, jacobian, evaluation, chi2_now)


_Refit = tuple[float, _Accepted, list[_Accepted], FloatArray, FloatArray, _Evaluation]


def _refit_with_rivals(
    fitter: _Fitter,
    scores: list[_Score],
    accepted: list[_Accepted],
    theta: FloatArray,
    chi2_now: float,
    scale: float,
    options: ReconcileOptions,
) -> tuple[list[_Refit], tuple[float, _Accepted] | None]:
    """The best candidate's non-linear refit, and its declared confusable rival's when their
    linearised scores are too close to tell; the better refit first. Returns the refits and,
    for a tie, (the rival's refit ΔBIC, the rival)."""
    best = scores[0]
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
    return fits, tie
