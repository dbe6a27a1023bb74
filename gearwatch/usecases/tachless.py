"""Records without a tachometer: the shaft angle from the mesh phase, and a tooth frame per campaign.

Two steps of the per-record chain (:mod:`gearwatch.usecases.analyze`) for rigs without a tach, or a
record whose tach channel is dead:

1. :func:`mesh_phase_angle` — synthetic once-per-pinion-revolution pulses from the phase of a
   mesh harmonic (:func:`dsp.tachless.tachless_shaft_angle`), on the accelerometer channel and
   harmonic that give the steadiest pulses; the refusal reasons of :mod:`dsp.tachless` when
   none does. The speed comes from ``[rig] nominal_pinion_rpm`` when given, else from the
   campaign's reference (the speed of its latest record numbered in its frame,
   :func:`fold_reference`), else from the
   comb of the spectrum's lines, checked against both shafts (the comb often locks on the
   other wheel's shaft); such a speed is then checked and corrected by the angle's own
   revolutions (:mod:`dsp.shaftperiod`, :mod:`gearwatch.usecases.shaft_angle`), and a
   record whose revolutions do not confirm it gets no per-tooth numbers
   (:attr:`FramePlacement.check_period`).
2. :func:`place_in_tooth_frame` — without a tach there is no absolute tooth 1: the averages
   are moved into the *campaign's* tooth frame by matching their tooth fingerprint to the
   campaign's reference (:mod:`dsp.toothframe`), or refused with the correlation margin.

The campaign frame is the tachometer's when the reference came from a tach record (a mixed
campaign: tach-less days are aligned to the tach days, ``tooth1_pitch_angle_deg`` keeps its
meaning), else the canonical frame of the first tach-less record: tooth 1's sector is centred
on that record's first mesh-harmonic maximum after its first synthetic pulse.

Pure: arrays and small dataclasses in and out; the caller stores the reference
(:func:`fold_reference`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np

from dsp.meshspectrum import DB_PER_NEPER
from dsp.tach import TachAnalysis, TachometerError, analyze_tachometer
from dsp.tachless import (
    MIN_LINE_PROMINENCE_DB,
    NEIGHBOUR_FRACTION,
    ShaftAngleEstimate,
    TachlessError,
    agreeing_harmonics,
    comb_shaft_cycles,
    comb_speed_hz,
    dechirped_prominence_db,
    estimate_pair_speed,
    line_prominence,
    tachless_shaft_angle,
)
from dsp.toothframe import (
    align_fingerprint,
    circular_shift,
    frame_delay_samples,
    loud_sectors,
    mesh_phase_position,
    resample_periodic,
    tooth_fingerprint,
)
from gearwatch.floor.results import AnalysisParameters, ChannelAnalysis, ToothFrameReference

__all__ = [
    "FOLD_RECORDS",
    "FramePlacement",
    "MeshPhaseAngle",
    "PlacedAverages",
    "fold_reference",
    "mesh_phase_angle",
    "place_in_tooth_frame",
    "tach_frame_fingerprints",
    "unsteady_angle",
]

MAX_HARMONIC = 8
"""Mesh harmonics 1..8 (below 0.45 fs) are tried; the one giving the steadiest synthetic pulses is kept."""
MAX_BANDWIDTH_ORDERS = 0.3
"""Half-width of the mesh band (shaft orders); narrower when the other wheel's sidebands are
closer (``0.75 × pinion/gear teeth``): their pattern repeats only once per hunting period."""
HARMONICS_TRIED = 3
"""…the three with the most prominent lines, each demodulated in full."""
SPEED_HINT_FRACTION = 0.2
"""The mesh line is looked for within ±20 % of the speed hint."""
SPECTRUM_SEARCH_FRACTION = 0.05
"""Around the speed found in the spectrum, the mesh line is looked for within ±5 % (a drifting
speed smears the line; the tracked band follows it, :func:`dsp.tachless.mesh_ridge_cycles`)."""
FOLD_RECORDS = 5
"""The reference fingerprint is the mean of the first 5 records aligned with confidence: a noisy
or spalled first record is diluted, and later changes (a growing spall) never enter it."""


@dataclass(frozen=True)
class MeshPhaseAngle:
    """Synthetic pinion pulses analysed like a tach, and what ``quality.tachless`` reports."""

    tach: TachAnalysis
    summary: dict[str, Any]


def _pulse_jitter_rev(pulse_times_s: np.ndarray) -> float:
    """Scatter of the pulses about a smooth speed, in revolutions.

    Independent angle errors of std σ (rev) give second differences of the pulse times of std
    σ·√6 periods; a smooth speed change gives almost none.
    """
    if pulse_times_s.size < 4:
        return math.nan
    period = float(np.mean(np.diff(pulse_times_s)))
    return float(np.std(np.diff(pulse_times_s, 2)) / (math.sqrt(6.0) * period))


def _pinion_speed_candidates(
    x: np.ndarray, sample_rate_hz: float, pinion_teeth: int, gear_teeth: int, hint_rpm: float | None
) -> list[float]:
    """Pinion speeds (Hz) worth trying: the hint, or the comb's speed read as either shaft's."""
    if hint_rpm is not None:
        return [hint_rpm / 60.0]
    duration_s = x.size / sample_rate_hz
    return [estimate_pair_speed(x, sample_rate_hz, pinion_teeth, gear_teeth,
                                min_shaft_hz=10.0 / duration_s)]


def _harmonic_window(harmonic: int, search: float) -> float:
    """Relative half-width of the window for mesh ``harmonic`` around the comb's speed."""
    return min(search, NEIGHBOUR_FRACTION / harmonic)


def _best_line(
    x: np.ndarray, sample_rate_hz: float, pinion_teeth: int, candidates: list[float], search: float
) -> tuple[float, float, list[int]]:
    """The candidate speed whose mesh harmonics stand highest; that speed refined on the whole
    record's mesh comb (:func:`dsp.tachless.comb_speed_hz`); and the harmonics by prominence, each
    looked for within :func:`_harmonic_window` of where the comb's speed puts it, without those
    whose line disagrees with the others' speed (:func:`dsp.tachless.agreeing_harmonics`).

    The drift pass starts again from the candidate: on a record whose speed swings, the whole
    record's comb can settle anywhere in the ±``search`` window."""
    prominence, freq = line_prominence(x, sample_rate_hz)
    bin_hz = float(freq[1])
    standing_np = MIN_LINE_PROMINENCE_DB / DB_PER_NEPER
    best: tuple[float, float, float, list[int]] | None = None
    for candidate_hz in candidates:
        comb_hz = comb_speed_hz(prominence, freq, pinion_teeth, candidate_hz, search_fraction=search)
        heights: dict[int, float] = {}
        peaks_hz: dict[int, float] = {}
        for h in range(1, MAX_HARMONIC + 1):
            expected = h * pinion_teeth * comb_hz
            if expected >= 0.45 * sample_rate_hz:
                break
            window = _harmonic_window(h, search)
            lo = max(1, int(expected * (1 - window) / bin_hz))
            hi = min(prominence.size - 1, math.ceil(expected * (1 + window) / bin_hz) + 1)
            if hi <= lo:
                continue
            peak = lo + int(np.argmax(prominence[lo:hi]))
            heights[h], peaks_hz[h] = float(prominence[peak]), float(freq[peak])
        standing = {h for h, height in heights.items() if height >= standing_np}
        for h in standing - agreeing_harmonics(peaks_hz, standing):
            del heights[h]
        if heights and (best is None or max(heights.values()) > best[0]):
            ranked = sorted(heights, key=lambda h: heights[h], reverse=True)
            best = (max(heights.values()), candidate_hz, comb_hz, ranked)
    if best is None:
        raise TachlessError(f"no mesh harmonic below 0.45 fs at about {candidates[0]:.6g} Hz")
    return best[1], best[2], best[3]


def _tracked_ranking(
    x: np.ndarray, sample_rate_hz: float, pinion_teeth: int, shaft_hz: float, search: float
) -> tuple[list[int], np.ndarray | None]:
    """The speed tracked on the mesh comb (:func:`dsp.tachless.comb_shaft_cycles`), and the mesh
    harmonics below 0.45 fs ranked by how far each stands out along it."""
    try:
        shaft_cycles = comb_shaft_cycles(x, sample_rate_hz, pinion_teeth, shaft_hz, search_fraction=search)
    except TachlessError:
        return [], None
    standing: dict[int, float] = {}
    duration_s = x.size / sample_rate_hz
    for h in range(1, MAX_HARMONIC + 1):
        if h * pinion_teeth * shaft_cycles[-1] / duration_s >= 0.45 * sample_rate_hz:
            break
        standing[h] = dechirped_prominence_db(x, h * pinion_teeth * shaft_cycles)
    return sorted(standing, key=lambda h: standing[h], reverse=True), shaft_cycles


def _angle_disagreement_teeth(a: ShaftAngleEstimate, b: ShaftAngleEstimate) -> float:
    """How far two mesh-phase angles of one record wander apart over it, in teeth: the spread
    (max − min) of ``b``'s revolutions at ``a``'s pulses minus ``a``'s."""
    inside = (a.pulse_times_s > b.pulse_times_s[0]) & (a.pulse_times_s < b.pulse_times_s[-1])
    if inside.sum() < 2:
        return math.nan
    at = np.interp(a.pulse_times_s[inside], b.pulse_times_s, np.arange(b.pulse_times_s.size, dtype=np.float64))
    offset = at - np.flatnonzero(inside)
    offset = (offset - offset[0] + 0.5) % 1.0 - 0.5  # whole revolutions are the pulses' numbering
    return float(np.ptp(offset) * a.mesh_order)


Candidate = tuple[float, ShaftAngleEstimate, str]
"""A working mesh-phase angle: (pulse jitter in revolutions, the estimate, its channel)."""

STEADY_SPEED_VARIATION = 0.02
"""Synthetic pulses whose per-revolution speed varies by more than 2 % swept the mesh line
across the transfer path's phase: see :func:`_chosen_estimate`."""


def unsteady_angle(summary: Mapping[str, Any]) -> str:
    """Why a mesh-phase angle is not steady enough for the tooth frame's second witness
    (:data:`dsp.toothframe.MIN_CONFIRMED_SEPARATION_Z`), or ``""``.

    Along a sweeping speed the angle read from a mesh harmonic wanders with the transfer path's
    phase (:func:`_chosen_estimate`): the waveform match's doubt between neighbouring teeth is
    then partly a real error of the angle, and the per-tooth energy pattern, read through the
    same angle, cannot lift it. Measured (``benchmarks/bench_tachless.py --simulator indep
    --max-drift 0.2``, seeds 9000–9019 and 9100–9119): with the confirmation on every record,
    4 more days were wrong by the tach's angle (6 → 10 of ~120 aligned); every day it had
    added there was such a record (speed variation 9–26 %, the line followed along the drift).

    Examples
    --------
    >>> unsteady_angle({"speed_variation": 0.004, "line_followed_along_drift": False})
    ''
    >>> unsteady_angle({"speed_variation": 0.12, "line_followed_along_drift": True})
    'the mesh line was followed along a drifting speed (12.0% within the record)'
    """
    variation = float(summary.get("speed_variation") or 0.0)
    if summary.get("line_followed_along_drift"):
        return f"the mesh line was followed along a drifting speed ({variation:.1%} within the record)"
    if variation > STEADY_SPEED_VARIATION:
        return f"the speed varied by {variation:.1%} within the record (steady: ≤ {STEADY_SPEED_VARIATION:.0%})"
    return ""


def _chosen_estimate(working: list[Candidate], followed_drift: bool) -> Candidate:
    """Which of the working candidates gives the angle.

    At a steady speed, the steadiest pulses (least jitter). When the speed sweeps — the steadiest
    first-pass pulses vary by more than :data:`STEADY_SPEED_VARIATION`, or only the drift pass
    works — the highest harmonic that works in either pass (then the least jitter): as
    the mesh frequency sweeps, the transfer path's phase at it turns, and the angle read from
    harmonic h wanders by that phase / (2π h) *teeth*. Measured: 0.4 of a tooth on harmonic 1
    against 0.1 on harmonic 5 of a ±20 % swing; a 66-tooth day sweeping ±8 % whose harmonic-1
    pulses were the steadiest landed 1.4 teeth off (held-out seed 8006 of
    ``benchmarks/bench_tachless.py --max-drift 0.2``, scored by the tach's angle).
    """
    steadiest = min(working, key=lambda item: item[0])
    if not followed_drift and steadiest[1].speed_variation <= STEADY_SPEED_VARIATION:
        return steadiest
    return min(working, key=lambda item: (-item[1].harmonic, item[0]))


def mesh_phase_angle(
    signals: Mapping[str, np.ndarray],
    sample_rate_hz: float,
    pinion_teeth: int,
    gear_teeth: int,
    params: AnalysisParameters,
    *,
    nominal_pinion_rpm: float | None = None,
) -> MeshPhaseAngle | str:
    """Once-per-pinion-revolution pulses from the mesh phase, or the reason there are none.

    Every accelerometer channel and mesh harmonic 1…:data:`MAX_HARMONIC` with a line is tried
    (:func:`dsp.tachless.tachless_shaft_angle`); the pulses with the smallest jitter
    (:func:`_pulse_jitter_rev`) win if their speed is steady. When none works (a speed drifting
    within the record smears the lines and moves them across each other's search windows), or
    the steadiest pulses sweep by more than :data:`STEADY_SPEED_VARIATION`, a second pass tracks
    the speed on the whole mesh comb and follows each line along it (``follow_drift``; harmonics
    ranked by how far they stand out there), and the highest harmonic that works in either pass
    wins (:func:`_chosen_estimate`). The winner goes through the tach checks of
    :func:`dsp.tach.analyze_tachometer` (revolutions, speed range, speed variation) with
    ``params``' limits. Returns a one-line reason (the first refusal of each channel) when
    nothing works.
    """
    bandwidth = min(MAX_BANDWIDTH_ORDERS, 0.75 * min(1.0, pinion_teeth / gear_teeth))
    refusals: list[str] = []
    best: Candidate | None = None
    followed_drift = False
    search = SPEED_HINT_FRACTION if nominal_pinion_rpm is not None else SPECTRUM_SEARCH_FRACTION
    lines: dict[str, tuple[np.ndarray, float, float, list[int]]] = {}
    for name, samples in signals.items():
        x = np.asarray(samples, dtype=np.float64)
        try:
            candidates = _pinion_speed_candidates(
                x, sample_rate_hz, pinion_teeth, gear_teeth, nominal_pinion_rpm
            )
            candidate_hz, comb_hz, harmonics = _best_line(x, sample_rate_hz, pinion_teeth, candidates, search)
        except TachlessError as error:
            refusals.append(f"{name}: {error}")
            continue
        lines[name] = (x, candidate_hz, comb_hz, harmonics)
    first_pass: list[Candidate] = []
    working_all: list[Candidate] = []
    for follow_drift in (False, True):
        working: list[Candidate] = []  # this pass's
        for name, (x, candidate_hz, comb_hz, harmonics) in lines.items():
            shaft_hz = candidate_hz if follow_drift else comb_hz
            shaft_cycles = None
            if follow_drift:
                harmonics, shaft_cycles = _tracked_ranking(x, sample_rate_hz, pinion_teeth, shaft_hz, search)
            first_refusal = ""
            found = False
            for harmonic in harmonics[:HARMONICS_TRIED]:
                try:
                    estimate = tachless_shaft_angle(
                        x, sample_rate_hz, pinion_teeth, approx_shaft_hz=shaft_hz, harmonic=harmonic,
                        bandwidth_orders=bandwidth, track_speed=True,
                        search_fraction=search if follow_drift else _harmonic_window(harmonic, search),
                        follow_drift=follow_drift, shaft_cycles=shaft_cycles,
                    )
                except TachlessError as error:
                    first_refusal = first_refusal or str(error)
                    continue
                working.append((_pulse_jitter_rev(estimate.pulse_times_s), estimate, name))
                found = True
            if first_refusal and not found:
                refusals.append(f"{name}{' (along the drift)' if follow_drift else ''}: {first_refusal}")
        working_all = first_pass + working if follow_drift else working
        if not follow_drift:
            first_pass = working
            chosen = _chosen_estimate(working, False) if working else None
            if chosen is not None and chosen[1].speed_variation <= STEADY_SPEED_VARIATION:
                best, followed_drift = chosen, False
                break  # lines that stand out in the whole record are preferred: steadier phase
        elif first_pass or working:
            # an unsteady first pass competes with the drift pass: the highest harmonic wins
            best = _chosen_estimate(first_pass + working, True)
            followed_drift = any(best is item for item in working)
    if best is None:
        return "; ".join(refusals) or "no accelerometer signal"
    _rank, estimate, name = best
    jitter = _pulse_jitter_rev(estimate.pulse_times_s)
    try:
        tach = analyze_tachometer(
            estimate.pulse_times_s, 1,
            max_speed_variation=params.max_speed_variation,
            min_revolutions=params.min_revolutions,
            min_speed_rpm=params.min_speed_rpm,
            max_speed_rpm=params.max_speed_rpm,
            bridge=False,  # synthetic pulses are an estimate: irregular ones are not patched
        )
    except TachometerError as error:
        return f"synthetic pulses from {name}, harmonic {estimate.harmonic}: {error}"
    others = [item[1] for item in working_all if item is not best and item[2] == name]
    spreads = [d for d in (_angle_disagreement_teeth(estimate, other) for other in others) if math.isfinite(d)]
    disagreement = round(max(spreads), 3) if spreads else None
    summary = {
        "channel": name,
        "harmonic": int(estimate.harmonic),
        "mesh_line_hz": float(estimate.mesh_line_hz),
        "line_prominence_db": float(estimate.line_prominence_db),
        "line_followed_along_drift": followed_drift,
        "min_envelope_ratio": float(estimate.min_envelope_ratio),
        "pulse_jitter_rev": float(jitter),
        "speed_variation": float(estimate.speed_variation),
        "bandwidth_orders": float(bandwidth),
        "speed_from": "nominal_pinion_rpm" if nominal_pinion_rpm is not None else "spectrum",
        # angle 0 of this record's own averages (before any tooth-frame shift), for an audit
        # against a tach recorded alongside
        "first_pulse_s": float(tach.pulse_times_s[0]),
        # how far another working harmonic's angle wanders from this one over the record (teeth;
        # None: no other): a sweep across the path's resonances moves each harmonic's angle by
        # its own phase / (2π h). Shown, not acted on: as a refusal rule (> 0.5 tooth) it caught
        # the wrong days of one seed range and none of another (docs/tachless.md).
        "harmonic_disagreement_teeth": disagreement,
    }
    return MeshPhaseAngle(tach=tach, summary=summary)


# --------------------------------------------------------------------------- tooth frame


@dataclass(frozen=True)
class FramePlacement:
    """How a tach-less record's averages are to be framed (see :func:`place_in_tooth_frame`)."""

    reference: ToothFrameReference | None
    """The campaign's reference for this channel; None: none yet (or not in campaign mode)."""
    campaign_mode: bool
    """False: no campaign context (one file on the command line), the record's own frame."""
    record_sha256: str
    refusal: str = ""
    """Non-empty: per-tooth numbers are refused before any alignment, for this reason."""
    unsteady_angle: str = ""
    """Non-empty (:func:`unsteady_angle`): the alignment must stand on the waveform match
    alone, without the per-tooth energy pattern's confirmation."""
    check_period: bool = False
    """The speed came from the spectrum (no ``[rig] nominal_pinion_rpm``, or a hint that gave no
    angle or was overruled): it can be a wrong member of the mesh-line family, so the
    revolutions must prove to be true ones (:func:`dsp.shaftperiod.check_shaft_period`) before
    any per-tooth number is given."""


@dataclass(frozen=True)
class PlacedAverages:
    pinion_average: np.ndarray
    gear_average: np.ndarray
    tooth1_pitch_angle_deg: float
    tooth_frame: dict[str, Any]
    fingerprints: dict[str, np.ndarray]
    """In the campaign frame, for :func:`fold_reference` (empty when the frame was refused)."""
    pinion_delay_samples: float = 0.0
    """``pinion_average = circular_shift(the record's own average, pinion_delay_samples)``: the
    same shift is applied to the leave-one-out averages of the tooth score (:mod:`dsp.toothscore`)."""


def _alignment_json(alignment: Any) -> dict[str, Any]:
    return {
        "shift_teeth": alignment.shift_teeth,
        "correlation": round(float(alignment.correlation), 4),
        "runner_up": round(float(alignment.runner_up), 4),
        "margin": round(float(alignment.margin), 4),
        "separation_z": round(float(alignment.separation_z), 2),
        # the per-tooth energy pattern's support for the shift (dsp.toothframe.sector_pattern_z)
        # and whether the shift needed it (accepted below 3.5 standard errors)
        "sector_pattern_z": round(float(alignment.sector_pattern_z), 2),
        "confirmed_by_sector_pattern": bool(alignment.confirmed_by_sector_pattern),
        # the record's loud tooth sectors (and their ringing) left out of a second attempt
        "left_out_sectors": list(alignment.left_out_sectors),
    }


def tach_frame_fingerprints(
    pinion_average: np.ndarray, gear_average: np.ndarray, pinion_teeth: int, gear_teeth: int
) -> dict[str, np.ndarray]:
    """Fingerprints of a tach record: the pinion's in the tach frame, the gear's canonical.

    ``pinion_position`` (a 1-element array, mesh periods) is where the pinion average's first
    mesh harmonic peaks in the tach frame.
    """
    per_tooth = pinion_average.size / pinion_teeth
    position = mesh_phase_position(pinion_average, pinion_teeth)
    return {
        "pinion": circular_shift(tooth_fingerprint(pinion_average, pinion_teeth), position),
        "pinion_position": np.array([position / per_tooth]),
        "gear": tooth_fingerprint(gear_average, gear_teeth),
    }


def place_in_tooth_frame(
    pinion_average: np.ndarray,
    gear_average: np.ndarray,
    pinion_teeth: int,
    gear_teeth: int,
    placement: FramePlacement,
    *,
    tach_tooth1_pitch_angle_deg: float,
) -> PlacedAverages:
    """Move a tach-less record's averages into the campaign's tooth frame (or say why not).

    ``tooth_frame["kind"]``: ``campaign`` (aligned to the reference, or founding it:
    ``founds_reference``), ``refused`` (ambiguous or non-matching pattern: per-tooth results
    must not be stored; the averages stay canonical) or ``own`` (no campaign context: tooth 1
    is the record's own first mesh-harmonic maximum — not comparable between records).
    """
    per_tooth = pinion_average.size / pinion_teeth
    fingerprint = tooth_fingerprint(pinion_average, pinion_teeth)
    gear_fingerprint = tooth_fingerprint(gear_average, gear_teeth)

    def canonical(average: np.ndarray, teeth: int) -> np.ndarray:
        return circular_shift(average, -mesh_phase_position(average, teeth))

    own_delay = -mesh_phase_position(pinion_average, pinion_teeth)
    own_pinion, own_gear = canonical(pinion_average, pinion_teeth), canonical(gear_average, gear_teeth)
    if placement.refusal:
        return PlacedAverages(own_pinion, own_gear, 0.0,
                              {"kind": "refused", "reason": placement.refusal}, {}, own_delay)
    if not placement.campaign_mode:
        return PlacedAverages(own_pinion, own_gear, 0.0, {
            "kind": "own",
            "note": "no campaign reference: tooth 1 is centred on this record's first mesh-harmonic "
                    "maximum; tooth numbers are not comparable with other records",
        }, {"pinion": fingerprint, "pinion_position": np.array([0.0]), "gear": gear_fingerprint},
            own_delay)
    reference = placement.reference
    if reference is None:
        return PlacedAverages(own_pinion, own_gear, 0.0, {
            "kind": "campaign",
            "reference_frame": "mesh_phase",
            "reference_sha256": placement.record_sha256,
            "founds_reference": True,
        }, {"pinion": fingerprint, "pinion_position": np.array([0.0]), "gear": gear_fingerprint},
            own_delay)

    reference_position = reference.pinion_position * per_tooth
    reference_canonical = circular_shift(
        resample_periodic(reference.pinion_fingerprint, pinion_average.size), -reference_position
    )
    alignment = align_fingerprint(fingerprint, reference_canonical, pinion_teeth,
                                  no_confirmation_reason=placement.unsteady_angle)
    if alignment.shift_teeth is None and (left_out := loud_sectors(pinion_average, pinion_teeth)).any():
        # a grown spall (and its ringing) reshapes its own sectors: the rest of the pattern may
        # still say where the teeth are
        retry = align_fingerprint(fingerprint, reference_canonical, pinion_teeth,
                                  no_confirmation_reason=placement.unsteady_angle,
                                  left_out_sectors=left_out)
        if retry.shift_teeth is not None:
            alignment = retry
    frame: dict[str, Any] = {
        "reference_frame": reference.frame,
        "reference_sha256": reference.record_sha256,
        "reference_records": reference.records,
        "pinion": _alignment_json(alignment),
    }
    if alignment.shift_teeth is None:
        frame.update(kind="refused", reason=f"tooth frame refused: {alignment.refusal}")
        return PlacedAverages(own_pinion, own_gear, 0.0, frame, {}, own_delay)
    pinion_delay = frame_delay_samples(
        pinion_average, pinion_teeth, alignment.delay_samples, reference_position
    )
    pinion = circular_shift(pinion_average, pinion_delay)
    fingerprints = {
        "pinion": circular_shift(fingerprint, -alignment.delay_samples + reference_position),
        "pinion_position": np.array([reference.pinion_position]),
    }
    gear = own_gear
    if reference.gear_fingerprint is not None:
        gear_alignment = align_fingerprint(gear_fingerprint, reference.gear_fingerprint, gear_teeth,
                                           no_confirmation_reason=placement.unsteady_angle)
        frame["gear"] = _alignment_json(gear_alignment)
        if gear_alignment.shift_teeth is not None:
            gear = circular_shift(
                gear_average,
                frame_delay_samples(gear_average, gear_teeth, gear_alignment.delay_samples, 0.0),
            )
            fingerprints["gear"] = circular_shift(gear_fingerprint, -gear_alignment.delay_samples)
        else:
            frame["gear"]["refusal"] = gear_alignment.refusal
    frame["kind"] = "campaign"
    tooth1 = tach_tooth1_pitch_angle_deg if reference.frame == "tachometer" else 0.0
    return PlacedAverages(pinion, gear, tooth1, frame, fingerprints, float(pinion_delay))


def fold_reference(
    reference: ToothFrameReference | None, channel: ChannelAnalysis, record_sha256: str
) -> ToothFrameReference | None:
    """The campaign's reference after this accepted record (None: unchanged / nothing to keep).

    * No reference yet: this record founds it (tach frame from a tach record, else its mesh frame).
    * A tach record while the reference is a tach-less one: the frame is re-anchored on the
      tachometer (later tach-less days are aligned to the tach days; earlier ones keep the
      reference they name in their ``tooth_frame``).
    * Otherwise the record's campaign-frame fingerprints are averaged in while the reference
      holds fewer than :data:`FOLD_RECORDS` records.

    Every accepted record leaves its pinion speed (``speed_rpm``): its angle came from a tach,
    from ``[rig] nominal_pinion_rpm``, from this speed or from a spectrum speed its revolutions
    confirmed, and its averages matched the campaign's fingerprint. The next tach-less record
    of a rig without a nominal speed starts its mesh-line search there.
    """
    prints = channel.frame_fingerprints
    kind = channel.tooth_frame.get("kind")
    if "pinion" not in prints or kind not in ("tachometer", "campaign"):
        return None
    frame: Literal["tachometer", "mesh_phase"] = "tachometer" if kind == "tachometer" else "mesh_phase"
    position = float(prints["pinion_position"][0])
    speed_rpm = (float(channel.speed_rpm) if channel.speed_rpm > 0
                 else None if reference is None else reference.speed_rpm)
    if reference is None or (reference.frame == "mesh_phase" and frame == "tachometer"):
        return ToothFrameReference(
            frame=frame, record_sha256=record_sha256,
            pinion_fingerprint=np.asarray(prints["pinion"], dtype=np.float64),
            pinion_position=position,
            gear_fingerprint=None if "gear" not in prints else np.asarray(prints["gear"], dtype=np.float64),
            speed_rpm=speed_rpm,
        )
    if reference.records >= FOLD_RECORDS:
        return None if speed_rpm == reference.speed_rpm else replace(reference, speed_rpm=speed_rpm)
    n = reference.records

    def mean(old: np.ndarray, new: np.ndarray) -> np.ndarray:
        folded = (n * resample_periodic(old, new.size) + new) / (n + 1)
        rms = float(np.sqrt(np.mean(folded**2)))
        return folded / rms if rms > 0 else folded

    # both in the campaign frame already: a tach record's is the tach frame itself
    pinion = mean(reference.pinion_fingerprint, np.asarray(prints["pinion"], dtype=np.float64))
    gear = reference.gear_fingerprint
    # a tach record's gear fingerprint is canonical but not aligned (the gear's starting tooth
    # depends on where the record starts in the hunting period): only aligned ones are folded
    if gear is not None and "gear" in prints and kind == "campaign":
        gear = mean(gear, np.asarray(prints["gear"], dtype=np.float64))
    return ToothFrameReference(
        frame=reference.frame, record_sha256=reference.record_sha256,
        pinion_fingerprint=pinion, pinion_position=reference.pinion_position,
        gear_fingerprint=gear, records=n + 1, speed_rpm=speed_rpm,
    )
