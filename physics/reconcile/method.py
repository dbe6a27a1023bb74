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
from dataclasses import dataclass
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from physics.config import GearPairModel
from physics.reconcile.catalogue import (
    CATALOGUE,
    NOT_SCANNED_BY_DEFAULT,
)
from physics.reconcile.discrepancy import (
    base_line_misfit,
    line_form_error_statement,
    with_line_misfit,
)
from physics.reconcile.fitter import (
    _Accepted,
    _calibration_json,
    _covariance,
    _Evaluation,
    _finding,
    _Fitter,
    _updated_model,
)
from physics.reconcile.honesty import assess, block_correlation
from physics.reconcile.localize import mismatches, nonsynchronous_mismatch
from physics.reconcile.observables import (
    HuntingSpectrum,
    gear_frame_shift,
    hunting_spectrum,
    shift_revolutions,
)
from physics.reconcile.progress import REFERENCE_SHARE, Progress, ProgressCallback, StageTicker
from physics.reconcile.results import (
    ComplexArray,
    Finding,
    FloatArray,
    MeasuredRecord,
    ReconcileOptions,
    ReconciliationResult,
    _clean,
    _round,
    honesty_status,
)
from physics.reconcile.selection import _select, _Selection

FRAME_EVIDENCE = 10.0
"""The best gear-frame shift must beat every other by this χ² (odds > 150 : 1) to be applied."""



def reconcile(
    measured: MeasuredRecord | HuntingSpectrum,
    model: GearPairModel,
    *,
    reference: MeasuredRecord | HuntingSpectrum | None = None,
    options: ReconcileOptions | None = None,
    progress: ProgressCallback | Progress | None = None,
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
    progress
        Called with ``(stage, fraction of the run done)`` as the run goes (e.g.
        :func:`physics.reconcile.progress.tqdm_progress`; the REST job stores it).

    Returns
    -------
    ReconciliationResult
    """
    with threadpool_limits(limits=BLAS_THREADS, user_api="blas"):
        return _reconcile(measured, model, reference, options, progress)


BLAS_THREADS = 1
"""BLAS threads while reconciling. The fitter's dense algebra is small (Jacobians of a few
hundred orders by tens of parameters): with OpenBLAS's threads the strong-spall case of
``benchmarks/bench_reconcile.py`` took 299 s of CPU and 197 s of wall time on an idle 2-core
machine, with one thread 179 s and 179 s — the threads spun more than they computed."""


def _reconcile(
    measured: MeasuredRecord | HuntingSpectrum,
    model: GearPairModel,
    reference: MeasuredRecord | HuntingSpectrum | None,
    options: ReconcileOptions | None,
    progress: ProgressCallback | Progress | None,
) -> ReconciliationResult:
    options = options or ReconcileOptions()
    prog = progress if isinstance(progress, Progress) else Progress(progress)
    own = prog.span(REFERENCE_SHARE, 1.0) if reference is not None else prog
    prog.report("observable", 0.0)
    t0 = time.perf_counter()
    spec = _spectrum(measured, model, options)
    target = spec.mean.copy()
    variance = spec.variance.copy()
    timings: dict[str, float] = {"observable": time.perf_counter() - t0}
    against: _Reference | None = None
    if reference is not None:
        against = _against_reference(reference, spec, variance, model, options,
                                     prog.span(0.0, REFERENCE_SHARE, "reference: "))
        spec, target, variance, model = against.spec, against.target, against.variance, against.model
        timings["reference"] = time.perf_counter() - t0 - timings["observable"]

    # 1. Base calibration.
    fitter = _Fitter(spec, target, variance, model, options)
    ticker = StageTicker(own)
    fitter.fm.on_simulation = ticker
    ticker.enter("calibration", 0.0, 1.0, 0)
    t1 = time.perf_counter()
    theta, jacobian, evaluation = fitter.fit([])
    line_misfit = 0.0
    if options.declare_line_misfit:
        line_misfit = _declared_line_misfit(fitter, theta, jacobian, evaluation, target, variance, options)
        if line_misfit > 0:
            # the mesh model's form error is declared on its own lines, and the base is
            # calibrated again under it (the first calibration bent itself to fit those lines)
            variance = with_line_misfit(variance, evaluation.prediction, line_misfit)
            fitter.set_variance(variance)
            theta, jacobian, evaluation = fitter.fit([], theta)
    timings["base_calibration"] = time.perf_counter() - t1
    base = _Base(
        evaluation, fitter.chi2(evaluation), fitter.dof(evaluation, []), target - evaluation.prediction,
        line_misfit,
    )
    # 2. Locate.
    located = _locate(fitter, base, variance, model, options, against)
    # 3. Explain.
    t2 = time.perf_counter()
    ticker.enter("selection", 0.0, 1.0, fitter.fm.simulations)
    selection = _select(fitter, theta, jacobian, evaluation, base.chi2, options)
    timings["selection"] = time.perf_counter() - t2
    own.stage("intervals", 0.0)
    # 4. Honesty guard, and the result.
    result = _result(
        fitter, target, variance, base, selection, located, against, model, options, timings, t0
    )
    own.report("done", 1.0)
    return result


def _declared_line_misfit(
    fitter: _Fitter,
    theta: FloatArray,
    jacobian: FloatArray,
    evaluation: _Evaluation,
    target: ComplexArray,
    variance: FloatArray,
    options: ReconcileOptions,
) -> float:
    """η (:mod:`physics.reconcile.discrepancy`) of the calibrated base, or 0 when one refitted
    structural mode brings the lines to their noise: a resonance the configuration lacks moves
    most lines, and the base calibrated without it bends to spread that misfit over all of them
    (the housing mode of ``tests/physics/reconcile/test_method.py``: η 0.9 at the base, none once
    the mode is fitted), which is a finding to make, not form error to declare."""
    eta = base_line_misfit(fitter, theta, evaluation, target, variance)
    if eta == 0.0 or "structural_mode" not in options.mechanisms:
        return eta
    modes_only = dataclasses.replace(options, mechanisms=("structural_mode",), max_findings=1)
    trial = _select(fitter, theta, jacobian, evaluation, fitter.chi2(evaluation), modes_only)
    if not trial.accepted:
        return eta
    return base_line_misfit(fitter, trial.theta, trial.evaluation, target, variance, trial.accepted)


@dataclass
class _Reference:
    """This record brought onto a reconciled healthy reference (step 0 with ``reference``)."""

    spec: HuntingSpectrum
    target: ComplexArray
    variance: FloatArray
    model: GearPairModel
    """The reference's updated model: what it needed is normal content of this rig."""
    json: dict[str, Any]
    nonsync: dict[str, Any] | None


def _against_reference(
    reference: MeasuredRecord | HuntingSpectrum,
    spec: HuntingSpectrum,
    variance: FloatArray,
    model: GearPairModel,
    options: ReconcileOptions,
    progress: Progress | None = None,
) -> _Reference:
    # The healthy reference is reconciled first; what it needs (runout, index errors,
    # modes the configuration lacks...) is normal content of this rig and goes into the
    # base, and its remaining residual is known model-form error: only the change is
    # explained.
    # Its residual is subtracted whatever it is, so its own selection only needs the rig's
    # strongest content (at most ``reference_max_findings``): each further round is a full
    # refit, and on long healthy records those rounds went to model-form error.
    ref_options = dataclasses.replace(
        options, max_findings=min(options.max_findings, options.reference_max_findings)
    )
    ref_result = reconcile(reference, model, options=ref_options, progress=progress)
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
    return _Reference(spec, target, variance, model, reference_json, ref_nonsync)


@dataclass
class _Base:
    """The calibrated base (step 1)."""

    evaluation: _Evaluation
    chi2: float
    dof: int
    residual: ComplexArray
    line_misfit: float = 0.0
    """η of :mod:`physics.reconcile.discrepancy` (0: the mesh lines fit to their noise)."""


def _locate(
    fitter: _Fitter,
    base: _Base,
    variance: FloatArray,
    model: GearPairModel,
    options: ReconcileOptions,
    against: _Reference | None,
) -> list[dict[str, Any]]:
    """Step 2: where the base's residual is, when χ² says there is one, and non-synchronous
    content in the scatter between hunting periods."""
    spec = fitter.spec
    freq = fitter.fm.frequency_hz
    tooth1 = model.tachometer.tooth1_pitch_angle_deg
    chi2_base, dof_base = base.chi2, base.dof
    located = mismatches(
        base.residual,
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
        if against is not None:
            ref_nonsync = against.nonsync
            nonsync["also_in_reference"] = bool(
                ref_nonsync is not None and ref_nonsync["band_hz"] == nonsync["band_hz"]
            )
        located.append(nonsync)
    return located


def _result(
    fitter: _Fitter,
    target: ComplexArray,
    variance: FloatArray,
    base: _Base,
    selection: _Selection,
    located: list[dict[str, Any]],
    against: _Reference | None,
    model: GearPairModel,
    options: ReconcileOptions,
    timings: dict[str, float],
    t0: float,
) -> ReconciliationResult:
    """Step 4: the findings at the final joint fit, the honesty guard, the JSON blocks."""
    spec = fitter.spec
    freq = fitter.fm.frequency_hz
    tooth1 = model.tachometer.tooth1_pitch_angle_deg
    accepted, findings, theta = selection.accepted, selection.findings, selection.theta
    jacobian, evaluation, chi2_now = selection.jacobian, selection.evaluation, selection.chi2
    base_eval, chi2_base, dof_base, base_residual = base.evaluation, base.chi2, base.dof, base.residual
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
    if base.line_misfit > 0 and status == "explained":
        # χ² is within its bounds only because the mesh lines' form error was declared as
        # noise: the lines themselves are not explained (an out-of-catalogue support change
        # must not pass as a match)
        status = "partly_explained" if accepted else "not_explained"
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
    final_findings, model_form = _model_form(
        fitter, accepted, jacobian, evaluation, final_findings, remaining, within,
        {"chi2_dof": chi2_dof_final, "chi2_dof_bounds": [1 - tolerance, 1 + tolerance]},
        options, base.line_misfit,
    )
    signal_energy = float(np.sum(np.abs(target[spec.used]) ** 2))
    baseline = {
        "mechanisms": _configured_mechanisms(model),
        "chi2_dof": _round(chi2_base / dof_base),
        "misfit": _round(float(np.sum(np.abs(base_residual[spec.used]) ** 2)) / signal_energy),
        "dof": dof_base,
        "calibrated": _calibration_json(fitter, theta[: len(fitter.nuisance)], base_eval.gains),
        "mesh_line_form_error": _round(base.line_misfit),
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
        model_form=model_form,
        unresolved=selection.unresolved,
        final=final,
        updated_model=updated,
        calibrated_base_model=calibrated_base,
        spectrum=spec,
        target=target,
        weights_variance=variance,
        base_prediction=base_eval.prediction,
        final_prediction=evaluation.prediction,
        candidates_scored=selection.scored_log,
        timings_s=timings,
        simulations=fitter.fm.simulations,
        reference=None if against is None else against.json,
        not_scanned={
            name: NOT_SCANNED_BY_DEFAULT.get(name, "not requested")
            for name in CATALOGUE
            if name not in options.mechanisms
        },
    )


def _model_form(
    fitter: _Fitter,
    accepted: list[_Accepted],
    jacobian: FloatArray,
    evaluation: _Evaluation,
    final_findings: list[Finding],
    remaining: list[dict[str, Any]],
    within: bool,
    provisional: dict[str, Any],
    options: ReconcileOptions,
    line_misfit: float,
) -> tuple[list[Finding], dict[str, Any]]:
    """Model-form honesty (honesty.py): findings that compensate for each other are one defect
    whose shape the catalogue lacks; only its lead stays a named finding. Returns the findings
    kept and the ``model_form`` block."""
    spec = fitter.spec
    blocks, start = [], len(fitter.nuisance)
    for a in accepted:
        blocks.append((start, start + len(a.mechanism.steps)))
        start += len(a.mechanism.steps)
    correlation = (
        block_correlation(_covariance(fitter, accepted, jacobian, evaluation, robust=False), blocks)
        if accepted else np.zeros((0, 0))
    )
    finding_dicts = [f.to_json() for f in final_findings]
    keep, model_form = assess(finding_dicts, correlation, provisional, [_clean(m) for m in remaining], within,
                              {"pinion": spec.pinion_teeth, "gear": spec.gear_teeth})
    for defect in model_form["defects"]:
        lead = final_findings[defect["finding_index"]]
        lead.model_form = defect["message"]
        defect["finding_index"] = keep.index(defect["finding_index"])
    model_form["not_separable_here"] = _not_separable(fitter, options)
    if line_misfit > 0:
        model_form["mesh_line_form_error"] = line_form_error_statement(line_misfit)
    return [final_findings[i] for i in keep], model_form


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


def _not_separable(fitter: _Fitter, options: ReconcileOptions) -> dict[str, str]:
    """Mechanisms this record's sensor cannot tell apart from others, and what would."""
    out = {}
    if not fitter.off_line and not options.friction_on_line_of_action and "sliding_friction" in options.mechanisms:
        out["sliding_friction"] = (
            "not looked for: on this line-of-action sensor friction acts only through its moments "
            "around the pitch point (mesh harmonics only), which a tip relief, the mesh stiffness "
            "shape and model-form error also produce; its own signature — the force reversing at "
            "the pitch point, across the line of action — needs an accelerometer off the line of "
            "action (or records at two loads: friction grows with μ·load, relief content shrinks)"
        )
    return out
