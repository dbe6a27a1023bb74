"""The record's shaft angle: the tachometer when it works, else the mesh phase, else the reason.

Part of the per-record chain (:mod:`gearwatch.usecases.analyze`). :func:`record_shaft_angle`
returns the tachometer analysis the angle resampling runs on — from the tach channel, or from
synthetic pulses at the mesh phase (:func:`gearwatch.usecases.tachless.mesh_phase_angle`) when the
tach is missing or unusable — or, when neither works, the reason as a string.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from fractions import Fraction
from typing import Any, Literal

import numpy as np

from dsp.robust import repair_spans
from dsp.shaftperiod import MODULI as PERIOD_MODULI
from dsp.shaftperiod import PeriodCheck, check_shaft_period
from dsp.tach import (
    RecordOutOfTachLimits,
    TachAnalysis,
    TachometerError,
    analyze_tachometer,
    pulse_times_from_waveform,
    pulse_times_from_waveform_blocks,
)
from dsp.tachless import TachlessError, estimate_pair_speed
from gearwatch.floor.campaign import Campaign, RecordData, TachometerConfig
from gearwatch.floor.errors import RecordFormatError, RecordRejected
from gearwatch.floor.results import AnalysisParameters
from gearwatch.usecases.angle_averages import angle_averages
from gearwatch.usecases.signal_checks import ScannedSignal, refuse_impossible_magnitudes
from gearwatch.usecases.tachless import MeshPhaseAngle, mesh_phase_angle


def _pinion_revs_per_tach_rev(campaign: Campaign) -> float:
    """Pinion revolutions per revolution of the shaft that carries the tachometer."""
    rig = campaign.rig
    shaft = campaign.tachometer.shaft if campaign.tachometer else "pinion"
    if not (rig.pinion_teeth and rig.gear_teeth):
        # Without tooth counts only the tach shaft itself can be averaged; call it the pinion.
        return 1.0
    return 1.0 if shaft == "pinion" else rig.gear_teeth / rig.pinion_teeth


@dataclass(frozen=True)
class ShaftAngle:
    """The record's shaft angle: tach pulses, or synthetic pulses from the mesh phase."""

    tach: TachAnalysis
    pinion_per_tach_rev: float
    tach_on_pinion: bool
    source: Literal["tachometer", "mesh_phase"]
    tach_failure: str = ""
    tachless: dict[str, Any] | None = None


def record_shaft_angle(
    record: RecordData,
    campaign: Campaign,
    params: AnalysisParameters,
    sample_rate_hz: float,
    block_samples: int,
    scans: Mapping[str, ScannedSignal],
    campaign_speed_rpm: float | None = None,
) -> ShaftAngle | str:
    """The tach when it works; else the mesh phase when the tooth counts allow; else the reason.

    A dead, missing or unusable tach channel does not lose the record: the angle comes from
    the mesh phase instead (:func:`gearwatch.usecases.tachless.mesh_phase_angle`) and ``quality`` says why.
    The mesh line is looked for near ``[rig] nominal_pinion_rpm``; without it, near
    ``campaign_speed_rpm`` (the speed of the campaign's latest record numbered in its tooth
    frame, :attr:`gearwatch.floor.results.ToothFrameReference.speed_rpm`), trusted as a
    nominal speed is (``speed_from = "campaign_speed_rpm"``); without either, the spectrum's
    speed, checked by the angle's revolutions.
    """
    tach_failure = ""
    if campaign.tachometer is not None:
        try:
            return ShaftAngle(
                tach=_analyze_tach(record, campaign, params, sample_rate_hz, block_samples),
                pinion_per_tach_rev=_pinion_revs_per_tach_rev(campaign),
                tach_on_pinion=campaign.tachometer.shaft == "pinion",
                source="tachometer",
            )
        except _RefusedWithAWorkingTach:
            raise
        except (RecordRejected, RecordFormatError) as error:
            tach_failure = " ".join(str(error).split())
    else:
        tach_failure = "the manifest has no [tachometer]"
    rig = campaign.rig
    if not (rig.pinion_teeth and rig.gear_teeth):
        return (
            f"no shaft angle: {tach_failure}, and without tooth counts ([rig] pinion_teeth, "
            "gear_teeth) the mesh phase cannot stand in for it"
        )
    # The mesh phase is read from the channels with their glitches, dropouts and clipped
    # stretches bridged, as the averages are: one corrupt sample (3e38) flattens the whole
    # record's spectrum and no mesh line would stand out.
    signals = {name: repair_spans(scan.samples, spans) if (spans := scan.defects.spans()).size
               else scan.samples for name, scan in scans.items()}
    record_signals = _MeshRecord(signals, scans, sample_rate_hz, rig.pinion_teeth, rig.gear_teeth,
                                 params, block_samples)
    hint_rpm, hint_source = rig.nominal_pinion_rpm, NOMINAL_SPEED
    if hint_rpm is None and campaign_speed_rpm is not None and campaign_speed_rpm > 0:
        hint_rpm, hint_source = float(campaign_speed_rpm), CAMPAIGN_SPEED
    mesh = record_signals.mesh_phase_angle(hint_rpm)
    if hint_rpm is None:
        mesh = _checked_spectrum_speed(mesh, record_signals)
    elif isinstance(mesh, str):
        mesh = _without_the_hint(mesh, record_signals)
    else:
        mesh = _hint_checked(mesh, record_signals, hint_source, hint_rpm)
    if isinstance(mesh, str):
        return f"no shaft angle: {tach_failure}; mesh phase: {mesh}"
    return ShaftAngle(
        tach=mesh.tach, pinion_per_tach_rev=1.0, tach_on_pinion=True, source="mesh_phase",
        tach_failure=tach_failure if campaign.tachometer is not None else "",
        tachless=mesh.summary,
    )


NOMINAL_SPEED = "nominal_pinion_rpm"
"""``quality.tachless.speed_from`` of an angle found near ``[rig] nominal_pinion_rpm``."""
CAMPAIGN_SPEED = "campaign_speed_rpm"
"""…near the speed of the campaign's latest record numbered in its tooth frame (no nominal
speed; ``campaign_speed_rpm`` in the summary says which)."""
OVERRULED = ", corrected by the revolutions"
"""Appended to the hint's ``speed_from`` when its revolutions overruled it (:func:`_hint_checked`);
``hint_speed_rpm`` keeps the speed the hint's angle had."""
TRUSTED_SPEEDS = (NOMINAL_SPEED, CAMPAIGN_SPEED)
"""Angles whose speed needs no check by their revolutions before per-tooth numbers
(:attr:`gearwatch.usecases.tachless.FramePlacement.check_period`): a hint within ±20 % of the
day's speed finds the right mesh line, and a hint far off is overruled or gives no angle."""
MAX_ANGLE_ATTEMPTS = 10
"""At most this many mesh-phase angles per record, the first included: each demodulates up to
three harmonics on every channel, and a pathological record must not try every ratio of every
prime (:func:`_checked_spectrum_speed`, :func:`_speed_corrected_by_revolutions`)."""


@dataclass
class _MeshRecord:
    """A record's accelerometer channels as the mesh-phase angle reads them (defects bridged),
    with what the speed check needs, and how many angles it has taken."""

    signals: Mapping[str, np.ndarray]
    scans: Mapping[str, ScannedSignal]
    sample_rate_hz: float
    pinion_teeth: int
    gear_teeth: int
    params: AnalysisParameters
    block_samples: int
    attempts: int = 0

    def mesh_phase_angle(self, hint_rpm: float | None) -> MeshPhaseAngle | str:
        """:func:`gearwatch.usecases.tachless.mesh_phase_angle` at ``hint_rpm``, or a refusal
        once :data:`MAX_ANGLE_ATTEMPTS` angles have been taken."""
        if self.attempts >= MAX_ANGLE_ATTEMPTS:
            return f"the speed search stopped after {MAX_ANGLE_ATTEMPTS} attempts"
        self.attempts += 1
        return mesh_phase_angle(self.signals, self.sample_rate_hz, self.pinion_teeth,
                                self.gear_teeth, self.params, nominal_pinion_rpm=hint_rpm)

    def period_check(self, mesh: MeshPhaseAngle) -> PeriodCheck:
        """Are the angle's revolutions true ones (:func:`dsp.shaftperiod.check_shaft_period`),
        on the channel that gave it. ``ValueError`` when the angle cannot resample it."""
        scan = self.scans[str(mesh.summary["channel"])]
        spm = self.params.samples_per_mesh
        angle = angle_averages(
            scan.samples, self.sample_rate_hz, mesh.tach.pulse_times_s, 1, self.pinion_teeth * spm,
            self.gear_teeth * spm, 1.0, self.gear_teeth // math.gcd(self.pinion_teeth, self.gear_teeth),
            self.block_samples, scan.defects, self.params.revolution_outlier_factor,
            period_moduli=PERIOD_MODULI,
        )
        assert angle.pinion_period_sums is not None  # asked for by period_moduli
        return check_shaft_period(angle.pinion_period_sums, angle.gear_period_sums,
                                  self.pinion_teeth, self.gear_teeth)


MAX_SPEED_CORRECTIONS = 3
"""How often a spectrum speed is corrected by what its revolutions say before it is left to be
refused (:func:`_speed_corrected_by_revolutions`)."""
RESCUE_SPEED_FACTORS = (2, 3, 4)
"""When the spectrum's speed gives no angle at all — a sub-multiple of the mesh frequency taken
for it leaves too few revolutions — these multiples of it are tried as hints
(:func:`_checked_spectrum_speed`)."""


def _checked_spectrum_speed(
    mesh: MeshPhaseAngle | str,
    record: _MeshRecord,
) -> MeshPhaseAngle | str:
    """The mesh-phase angle of a rig without ``nominal_pinion_rpm``, its speed checked and
    corrected by its own revolutions (:func:`_speed_corrected_by_revolutions`). When the
    spectrum's speed gave no angle (``mesh`` is the refusal), :data:`RESCUE_SPEED_FACTORS` × that
    speed are tried and the first angle the revolutions confirm is kept; none: the refusal."""
    if not isinstance(mesh, str):
        return _speed_corrected_by_revolutions(mesh, record)[0]
    duration_s = min(x.size for x in record.signals.values()) / record.sample_rate_hz
    for x in record.signals.values():
        try:
            spectrum_hz = estimate_pair_speed(np.asarray(x, dtype=np.float64), record.sample_rate_hz,
                                              record.pinion_teeth, record.gear_teeth,
                                              min_shaft_hz=10.0 / duration_s)
        except TachlessError:
            continue
        for factor in RESCUE_SPEED_FACTORS:
            hint_rpm = 60.0 * spectrum_hz * factor
            rescued = record.mesh_phase_angle(hint_rpm)
            if isinstance(rescued, str):
                continue
            start = MeshPhaseAngle(rescued.tach, {
                **rescued.summary, "speed_from": "spectrum", "speed_corrected_by": str(factor),
                "spectrum_speed_rpm": round(60.0 * spectrum_hz, 3), "corrected_speed_hint_rpm": hint_rpm,
            })
            corrected, confirmed = _speed_corrected_by_revolutions(
                start, record, total=Fraction(factor), spectrum_rpm=60.0 * spectrum_hz)
            if confirmed:
                return corrected
        break  # the first channel with a spectrum speed decides, as in mesh_phase_angle
    return mesh


def _without_the_hint(
    refusal: str,
    record: _MeshRecord,
) -> MeshPhaseAngle | str:
    """The speed hint gave no angle (the rig ran that day far from ``nominal_pinion_rpm``): the
    spectrum's speed, checked by the revolutions as without a hint; ``summary["hint_failed"]``
    keeps why the hint failed. Nothing either: the hint's refusal."""
    mesh = _checked_spectrum_speed(record.mesh_phase_angle(None), record)
    if isinstance(mesh, str):
        return refusal
    return MeshPhaseAngle(mesh.tach, {**mesh.summary, "hint_failed": refusal})


def _hint_checked(
    mesh: MeshPhaseAngle,
    record: _MeshRecord,
    hint_source: str,
    hint_rpm: float,
) -> MeshPhaseAngle:
    """An angle found near the hint (``nominal_pinion_rpm`` or the campaign's speed,
    ``hint_source``), replaced only when its revolutions show it a whole ratio off *and* the
    corrected angle's revolutions are confirmed; ``speed_from`` says which hint, and whether it
    was overruled.

    Within ±20 % of a right hint the angle is right; a hint that is wrong that day by more (the
    rig run at another speed) lets the search lock on another mesh harmonic, e.g. 1.5× or 2× the
    true speed, and every tooth number would be wrong. An unconfirmed correction keeps the
    hint's angle: a right angle's classes can differ a little through content that repeats only
    once per hunting period (docs/tachless.md), and the hint is then trusted as before."""
    corrected, confirmed = _speed_corrected_by_revolutions(mesh, record)
    if not confirmed or corrected is mesh:
        if hint_source == CAMPAIGN_SPEED:  # mesh_phase_angle calls every hint the nominal speed
            return MeshPhaseAngle(mesh.tach, {**mesh.summary, "speed_from": CAMPAIGN_SPEED,
                                              "campaign_speed_rpm": hint_rpm})
        return mesh
    summary = {key: value for key, value in corrected.summary.items() if key != "spectrum_speed_rpm"}
    return MeshPhaseAngle(corrected.tach, {
        **summary, "speed_from": hint_source + OVERRULED, "hint_overruled": True,
        "hint_speed_rpm": round(float(mesh.tach.mean_rpm), 3),
    })


def _speed_corrected_by_revolutions(
    mesh: MeshPhaseAngle,
    record: _MeshRecord,
    *,
    total: Fraction = Fraction(1),
    spectrum_rpm: float | None = None,
) -> tuple[MeshPhaseAngle, bool]:
    """A speed found in the spectrum, corrected when its revolutions show it a whole ratio off;
    and whether the revolutions of the angle returned are confirmed as true ones.

    Without ``[rig] nominal_pinion_rpm`` the speed is the mesh-line family's best fit, which is
    sometimes 2, 2.5 or 3 times the true one, or half of it (docs/tachless.md). The angle's
    revolutions say which (:attr:`dsp.shaftperiod.PeriodCheck.speed_factor`: residue classes
    that differ mean too fast, orders without content too slow), one prime at a time, so the
    angle is taken again at the corrected speed, as if it had been the hint, up to
    :data:`MAX_SPEED_CORRECTIONS` times (2.5× takes two: ÷5, then ×2); when ÷m gives no angle,
    the other ratios the prime allows (:attr:`dsp.shaftperiod.PeriodCheck.speed_factors`: 1.5×
    shows 3, and ÷3 leaves too few revolutions where ×2/3 does not). The per-channel check of
    the final angle still decides whether per-tooth numbers are given
    (:mod:`gearwatch.usecases.analyze`); ``summary["speed_corrected_by"]`` says what was
    done, ``summary["spectrum_speed_rpm"]`` what the spectrum gave and
    ``summary["corrected_speed_hint_rpm"]`` the hint the final angle was taken with.
    """
    if spectrum_rpm is None:
        spectrum_rpm = float(mesh.tach.mean_rpm)
    for attempt in range(MAX_SPEED_CORRECTIONS + 1):
        try:
            check = record.period_check(mesh)
        except ValueError:  # the angle cannot resample the record: left to the chain's refusal
            return mesh, False
        if not check.refusal or not check.speed_factors or attempt == MAX_SPEED_CORRECTIONS:
            return mesh, not check.refusal
        corrected: MeshPhaseAngle | str = "no correction"
        for factor in check.speed_factors:
            hint_rpm = float(mesh.tach.mean_rpm * factor)
            corrected = record.mesh_phase_angle(hint_rpm)
            if not isinstance(corrected, str):
                break
        if isinstance(corrected, str):
            return mesh, False
        total *= factor
        mesh = MeshPhaseAngle(corrected.tach, {
            **corrected.summary, "speed_from": "spectrum", "speed_corrected_by": str(total),
            "spectrum_speed_rpm": round(spectrum_rpm, 3), "corrected_speed_hint_rpm": hint_rpm,
        })
    return mesh, False


class _RefusedWithAWorkingTach(RecordRejected):
    """The tach measured the record itself failing (:class:`dsp.tach.RecordOutOfTachLimits`), or
    its channel holds impossible values (a broken acquisition, not a dead tach): the mesh phase
    would not rescue the record, so it is refused instead of analysed without the tach."""


def _analyze_tach(
    record: RecordData,
    campaign: Campaign,
    params: AnalysisParameters,
    sample_rate_hz: float,
    block_samples: int,
) -> TachAnalysis:
    config = campaign.tachometer
    if config is None:
        raise RecordRejected(
            "the manifest has no [tachometer]: synchronous averaging needs a once-per-revolution reference"
        )
    raw = record.channel(config.channel)
    try:
        refuse_impossible_magnitudes(raw, f"tachometer channel {config.channel!r}", block_samples)
    except RecordRejected as error:
        raise _RefusedWithAWorkingTach(str(error)) from error
    try:
        if config.kind == "pulses" and raw.size > block_samples:
            # NaN/inf are refused block by block inside
            pulse_times_s = pulse_times_from_waveform_blocks(
                raw, sample_rate_hz, block_samples=block_samples, edge=config.edge
            )
        else:
            raw = np.asarray(raw, dtype=np.float64)
            if not np.all(np.isfinite(raw)):
                raise RecordRejected(
                    f"tachometer channel {config.channel!r} contains NaN or inf samples"
                )
            pulse_times_s = (
                pulse_times_from_waveform(raw, sample_rate_hz, edge=config.edge)
                if config.kind == "pulses" else raw
            )
        try:
            tach = _tach_analysis(pulse_times_s, config.pulses_per_rev, params)
        except TachometerError as error:
            tach, failure = None, error
        if config.kind == "pulses" and (
            tach is None or tach.bridged_spans_s
            or _stops_short(pulse_times_s, raw.size / sample_rate_hz)
        ):
            # fixed levels may have missed edges of a waveform whose levels drift or fade: read
            # it against its local levels, and keep that reading if it is better
            retried = _with_tracking_levels(raw, sample_rate_hz, pulse_times_s, config, params,
                                            block_samples)
            if retried is not None and (tach is None or _better(retried, tach)):
                tach = retried
        if tach is None:
            raise failure
        return tach
    except RecordOutOfTachLimits as error:
        raise _RefusedWithAWorkingTach(f"tachometer: {error}") from error
    except TachometerError as error:
        raise RecordRejected(f"tachometer: {error}") from error


def _tach_analysis(pulse_times_s: np.ndarray, pulses_per_rev: int, params: AnalysisParameters) -> TachAnalysis:
    return analyze_tachometer(
        pulse_times_s,
        pulses_per_rev,
        max_speed_variation=params.max_speed_variation,
        min_revolutions=params.min_revolutions,
        min_speed_rpm=params.min_speed_rpm,
        max_speed_rpm=params.max_speed_rpm,
    )


def _bridged_s(tach: TachAnalysis) -> float:
    return sum(hi - lo for lo, hi in tach.bridged_spans_s)


def _better(retried: TachAnalysis, first: TachAnalysis) -> bool:
    """Less bridged, or as little bridged and more revolutions."""
    return (_bridged_s(retried), -retried.whole_revolutions) < (_bridged_s(first), -first.whole_revolutions)


def _stops_short(pulse_times_s: np.ndarray, duration_s: float) -> bool:
    """The pulses start or end more than 3 periods inside the record (a tach that fades, or that
    drifts out of the fixed levels, at one end)."""
    if pulse_times_s.size < 3:
        return False
    period = float(np.median(np.diff(pulse_times_s)))
    return bool(pulse_times_s[0] > 3 * period or duration_s - pulse_times_s[-1] > 3 * period)


def _with_tracking_levels(
    raw: Any,
    sample_rate_hz: float,
    first_reading: np.ndarray,
    config: TachometerConfig,
    params: AnalysisParameters,
    block_samples: int,
) -> TachAnalysis | None:
    """The tach read against its local levels (:mod:`dsp.tachlevels`), or ``None`` when that
    fails too or the first reading gave no period to size the levels' window by."""
    # scipy.ndimage only for a drifting tach: the chain with a sound tach loads no scipy
    from dsp.tachlevels import pulse_times_tracking_levels

    if first_reading.size < 3:
        return None
    period_s = float(np.median(np.diff(first_reading)))
    try:
        pulses = pulse_times_tracking_levels(raw, sample_rate_hz, period_s,
                                             block_samples=block_samples, edge=config.edge)
        return _tach_analysis(pulses, config.pulses_per_rev, params)
    except TachometerError:
        return None

