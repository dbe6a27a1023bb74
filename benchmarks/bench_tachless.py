"""Benchmark: tach-less campaigns against the same campaigns WITH the tachometer (issue 11).

    nice -n 10 .venv/bin/python benchmarks/bench_tachless.py [--seeds 1000-1019] [--days 8]
        [--seconds 4] [--cache .bench-cache/tachless] [--simulator physics|indep] [--json OUT]

Each seed draws one campaign: tooth counts 13–80 on both wheels (module scaled to a fixed centre
distance, 25° pressure angle below 18 teeth so the small wheel is not undercut), the speed
drifting by up to ±3 % within a record (and ±1 % from day to day), sensor noise 0.3–3 × the
signal's RMS (log-uniform per campaign, ±15 % per day), a spall on a random pinion tooth from a
random day after the baseline that grows daily (:func:`physics.campaign.campaign_plan`). Records are
simulated once and cached (noise is added afterwards, so the cache holds the noise-free physics).

Both chains run :func:`gearwatch.usecases.analyze.analyze_record` day by day:

* **tach** — the manifest with its tachometer;
* **tach-less** — the same records, the tach channel *removed* from the manifest; each day is
  placed in the campaign's tooth frame against the reference folded so far
  (:func:`gearwatch.usecases.tachless.fold_reference`, exactly what :mod:`gearwatch.usecases.ingest_file` stores).

Scored (the tach is used only to score):

* **alignment** per tach-less day after the first: *right* when its campaign-frame pinion average
  sits where the tach says (the shift between its campaign-frame and tach-frame averages equals
  the reference day's within half a mesh period), *refused*, or *wrong*;
* **alignment by the tach's angle** (``alignment_by_pulses``, ``pulse_offsets_teeth``, and
  ``pulse_evidence``: each such day's separation z, sector-pattern z and speed variation): the same
  days scored by where the tach puts sample 0 of the campaign-frame average — the circular mean,
  over the record's synthetic pulses, of the tach's angle at each, moved by the frame's
  ``pinion_delay_samples`` — against the founding day's; *right* within half a tooth. It does not
  depend on how alike a day's tach and tach-less averages look, which the first truth does (a
  speed sweeping through the path's resonances changes an average's shape, and so does a fresh
  spall: on those days the averages' best match can be a tooth off while the frame is right);
* **the speed** of every numbered tach-less day against the tach's (``speed_ratios``;
  ``numbered_at_a_wrong_speed`` counts those more than 3 % off): a frame found every day at half
  the speed is consistent from day to day — both truths above call it right — and numbers
  nothing right (added 2026-11-28, after development seed 1016 of the independent generator,
  56/28 teeth, was found so);
* **first alarm day** and **alarmed tooth** of one fixed bench rule on ``mci_depth``
  (:class:`detection.alarms.RuleSettings`: baseline from the first 4 days, warning at 4 robust
  spreads, persistence 2) in both chains; the tach-less tooth is mapped to the tach numbering
  through the reference day (both chains' averages of that day, matched over all sample shifts).
* the same for **the default per-tooth rules** an operator gets (``change`` + ``score``, as
  ``benchmarks/bench_detection.py`` evaluates them: :func:`_product_first_alarm`), and in how many
  campaigns each chain's first alarm names the spalled tooth.

Study switches: ``--no-guard`` (with ``--no-hint``) keeps the tooth frame of a day whose speed
came from the spectrum whatever its revolutions say (:func:`dsp.shaftperiod.check_shaft_period`
always passes), and ``GW_SPEED_STUDY=1`` adds to each row the days' spectrum speed against
the tach's and the line families' scores (docs/tachless.md, "Can the spectrum's speed be
trusted").

``--seconds`` sets the record length (default 4 s, about 67 revolutions; the project's campaigns
record 12 s): docs/tachless.md, "Record length", has both on fresh seeds 10010–10049.

Seeds 1000–1009 were used while choosing the refusal thresholds of :mod:`dsp.toothframe`
(development); the table reports them apart from the held-out seeds 2000–2019. Later sessions
spent further ranges once each (3000–9219, docs/tachless.md); 1000–1019 were dumped to choose the
energy-pattern confirmation and 9300–9319 held it out (seventh session). The speed check by the
revolutions (``--no-hint``) was chosen on 1000–1019 and held out on 9810–9839 (2026-11-28).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from detection.alarms import RuleSettings, TrackState, step
from dsp.tach import pulse_times_from_waveform
from dsp.teeth import tooth_at_angle
from gearwatch.floor.campaign import (
    Campaign,
    ChannelConfig,
    RecordData,
    RigConfig,
    TachometerConfig,
)
from gearwatch.floor.errors import RecordRejected
from gearwatch.floor.results import AnalysisParameters, RecordAnalysis, ToothFrameReference
from gearwatch.usecases.analyze import analyze_record
from gearwatch.usecases.tachless import fold_reference, mesh_phase_angle

DEV_SEEDS = range(1000, 1010)
HELD_OUT_SEEDS = range(2000, 2020)
BASELINE_DAYS = 4
NOMINAL_RPM = 1000.0
"""The simulator's nominal pinion speed, given as ``[rig] nominal_pinion_rpm`` (``--no-hint``: not)."""
RULE = RuleSettings("mci_depth", baseline_records=BASELINE_DAYS, spread_floor_abs=0.1, persistence=2)


@dataclasses.dataclass(frozen=True)
class Spec:
    seed: int
    pinion_teeth: int
    gear_teeth: int
    noise_ratio: float
    spall_tooth: int
    onset_day: int
    days: int


def campaign_spec(seed: int, days: int) -> Spec:
    rng = np.random.default_rng(seed)
    zp, zg = (int(v) for v in rng.integers(13, 81, size=2))
    return Spec(
        seed=seed, pinion_teeth=zp, gear_teeth=zg,
        noise_ratio=float(np.exp(rng.uniform(np.log(0.3), np.log(3.0)))),
        spall_tooth=int(rng.integers(1, zp + 1)),
        onset_day=int(rng.integers(BASELINE_DAYS + 1, days)),
        days=days,
    )


def _simulate_days(spec: Spec, seconds: float, cache: Path) -> list[dict[str, np.ndarray]]:
    """Noise-free acc + tach per day, cached as npz."""
    from physics.campaign import campaign_plan
    from physics.config import GearPairModel
    from physics.simulator import simulate

    files = [cache / f"seed{spec.seed}-{spec.days}d-{seconds:g}s-day{d + 1:02d}.npz" for d in range(spec.days)]
    if all(f.exists() for f in files):
        return [dict(np.load(f)) for f in files]
    base = GearPairModel()
    geometry = dataclasses.replace(
        base.geometry, pinion_teeth=spec.pinion_teeth, gear_teeth=spec.gear_teeth,
        module_mm=round(10.0 * 41 / (spec.pinion_teeth + spec.gear_teeth), 3),
        pressure_angle_deg=25.0 if min(spec.pinion_teeth, spec.gear_teeth) < 18 else 20.0,
    )
    base = base.replace(
        geometry=geometry,
        sensors=[dataclasses.replace(s, noise_rms_m_s2=0.0) for s in base.sensors],
    )
    plans = campaign_plan(spec.days, spec.spall_tooth, spec.onset_day, spec.seed, base_model=base)
    rng = np.random.default_rng(spec.seed + 7)
    cache.mkdir(parents=True, exist_ok=True)
    out = []
    for plan, path in zip(plans, files, strict=True):
        operating = dataclasses.replace(
            plan.model.operating, speed_drift_fraction=float(rng.uniform(-0.01, 0.01))
        )
        result = simulate(plan.model.replace(operating=operating), seconds=seconds, seed=plan.seed)
        acc_name = plan.model.sensors[0].name
        day = {
            "acc": result.channels[acc_name].astype(np.float32),
            "tach": result.channels[plan.model.tachometer.name].astype(np.float32),
            "fs": np.array(result.sample_rate_hz),
            "tooth1": np.array(result.tooth1_pitch_angle_deg),
        }
        np.savez(path, **day)
        out.append(day)
    return out


MAX_DRIFT = 0.05
"""In-record speed drift of the independent generator's campaigns: uniform in 0 … this
(``--max-drift``; the issue asks for drifts up to ±20 % to be analysed)."""


def _independent_days(spec: Spec, seconds: float, cache: Path) -> list[dict[str, np.ndarray]]:
    """The same campaign drawn by the independent generator (``physics.independent``, engineer
    indep): its own rig for the seed (tooth counts as the spec), index and profile errors, pits
    growing 4 → 25 µm from the onset day; noise given to it relative to the signal (so not
    added again: ``noise_ratio`` is passed as its ``noise_to_signal``), in-record drift up to
    :data:`MAX_DRIFT` (a ramp plus a slow swell, the generator's speed shape)."""
    from physics.independent import Spall, campaign_days, generate_record, random_model

    drift = "" if MAX_DRIFT == 0.05 else f"-drift{MAX_DRIFT:g}"
    files = [cache / f"indep{spec.seed}-{spec.days}d-{seconds:g}s{drift}-day{d + 1:02d}.npz"
             for d in range(spec.days)]
    if all(f.exists() for f in files):
        return [dict(np.load(f)) for f in files]
    rng = np.random.default_rng(spec.seed + 3)
    base = random_model(spec.seed, pinion_teeth=spec.pinion_teeth, gear_teeth=spec.gear_teeth,
                        noise_to_signal=spec.noise_ratio, seconds=seconds,
                        speed_drift_fraction=float(rng.uniform(0.0, 0.05)) * MAX_DRIFT / 0.05)
    plan = campaign_days(base, spec.days, onset_day=spec.onset_day, spall=Spall(tooth=spec.spall_tooth),
                         face_fractions=(0.15, 0.25, 0.4, 0.6), extents=(0.15, 0.25, 0.4, 0.55),
                         speed_jitter=0.02, seed=spec.seed)
    cache.mkdir(parents=True, exist_ok=True)
    out = []
    for day, path in zip(plan, files, strict=True):
        record = generate_record(day.model, seed=day.seed)
        campaign = record.campaign()
        entry = {
            "acc": record.channels["acc"].astype(np.float32),
            "tach": record.channels["tach"].astype(np.float32),
            "fs": np.array(record.sample_rate_hz),
            "tooth1": np.array(campaign.rig.tooth1_pitch_angle_deg),
            "rpm": np.array(base.operating.speed_rpm),
            "noise_added": np.array(1.0),
        }
        np.savez(path, **entry)
        out.append(entry)
    return out


def _campaigns(spec: Spec, tooth1: float, fs: float, hint: bool = True,
               rpm: float = 0.0) -> tuple[Campaign, Campaign]:
    rig = RigConfig("bench", spec.pinion_teeth, spec.gear_teeth, tooth1_pitch_angle_deg=tooth1 % 360.0,
                    nominal_pinion_rpm=(rpm or NOMINAL_RPM) if hint else None)
    acc = ChannelConfig("acc", "accelerometer")
    with_tach = Campaign(f"tach-{spec.seed}", "", rig, fs, TachometerConfig("tach"),
                         (acc, ChannelConfig("tach", "tachometer")))
    without = Campaign(f"tachless-{spec.seed}", "", rig, fs, None, (acc,))
    return with_tach, without


def _first_alarm(day_teeth: list[dict[int, float] | None]) -> tuple[int | None, int | None]:
    """(first day with an open warning/alarm on any tooth, that tooth) under :data:`RULE`."""
    states: dict[int, TrackState] = {}
    for day, teeth in enumerate(day_teeth, start=1):
        if teeth is None:
            continue
        raised = []
        for tooth, value in teeth.items():
            evaluation = step(states.get(tooth, TrackState()), value, RULE)
            states[tooth] = evaluation.state
            if evaluation.state.alarm_state is not None:
                raised.append((value, tooth))
        if raised:
            return day, max(raised)[1]
    return None, None


def _campaign_frame_angle_rev(tach: np.ndarray, record: RecordData, campaign: Campaign,
                              params: AnalysisParameters, frame: dict[str, Any],
                              samples_per_rev: int, tachless: dict[str, Any]) -> float:
    """The tach's pinion angle (revolutions, mod 1) at sample 0 of a tach-less day's
    campaign-frame average.

    Sample 0 of the record's own average sits, on average over its revolutions, at the circular
    mean of the tach's angle at the synthetic pulses (the mesh-phase angle the analysis used,
    recomputed here: the same function on the same samples); the frame's
    ``pinion_delay_samples`` moves it. A second truth beside the averages' best match, which
    depends on how alike a day's two averages look (a speed sweeping through the path's
    resonances, a fresh spall). The mean over the pulses, not the first pulse alone: along a
    sweep the angle read from the mesh phase wanders with the path's phase, and the average
    sits where the wander's mean puts it. A spectrum speed the revolutions corrected is taken
    again with the hint the chain used (``tachless["corrected_speed_hint_rpm"]``), and without
    the manifest's hint when that gave no angle (``tachless["hint_failed"]``); a day found near the
    campaign's learned speed with it (``tachless["campaign_speed_rpm"]``)."""
    rig = campaign.rig
    assert rig.pinion_teeth is not None and rig.gear_teeth is not None
    angle = mesh_phase_angle({"acc": np.asarray(record.channels["acc"], dtype=np.float64)},
                             record.sample_rate_hz, rig.pinion_teeth, rig.gear_teeth, params,
                             nominal_pinion_rpm=tachless.get(
                                 "corrected_speed_hint_rpm",
                                 None if "hint_failed" in tachless
                                 else tachless.get("campaign_speed_rpm", rig.nominal_pinion_rpm)))
    assert not isinstance(angle, str), angle
    synthetic = angle.tach.pulse_times_s
    pulses = pulse_times_from_waveform(tach, record.sample_rate_hz)  # once per pinion revolution
    inside = (synthetic > pulses[0]) & (synthetic < pulses[-1])
    at = np.interp(synthetic[inside], pulses, np.arange(pulses.size, dtype=np.float64))
    at = at - np.flatnonzero(inside)  # pulse i is i revolutions after pulse 0
    own_angle = float(np.angle(np.mean(np.exp(2j * np.pi * at))) / (2 * np.pi))
    return (own_angle - float(frame["pinion_delay_samples"]) / samples_per_rev) % 1.0


def _product_first_alarm(days: list[tuple[np.ndarray, float, list[float]] | None],
                         pinion_teeth: int) -> tuple[int | None, int | None]:
    """(first day, named tooth) of the per-tooth rules an operator gets by default: ``change``
    (:mod:`dsp.toothchange` on the day's pinion average in the chain's frame, exactly what
    :mod:`gearwatch.usecases.tooth_change` computes from the database) and ``score``, with their
    default settings, evaluated as ``benchmarks/bench_detection.py`` does (the tooth named is the
    top opening of the first day). ``days``: per day (pinion average, tooth 1's pitch angle, the
    per-tooth scores), None for a day without per-tooth results (refused, no angle)."""
    from bench_detection import (  # the same evaluation as the detection bench
        BOTH_PER_TOOTH,
        evaluate,
    )

    from dsp.toothchange import campaign_change_scores

    kept = [d for d in days if d is not None]
    changes = iter(campaign_change_scores([d[0] for d in kept], [d[1] for d in kept], pinion_teeth))
    result_days: list[dict[str, Any]] = []
    for number, day in enumerate(days, start=1):
        if day is None:
            result_days.append({"day": number, "rejected": "no per-tooth result"})
            continue
        change = next(changes)
        result_days.append({"day": number, "teeth": {
            "change": [math.nan] * pinion_teeth if change is None else [float(v) for v in change],
            "score": [float(v) for v in day[2]],
        }})
    openings = evaluate({"spec": {"pinion_teeth": pinion_teeth}, "days": result_days},
                        BOTH_PER_TOOTH, True, {})
    if not openings:
        return None, None
    first = min(o[0] for o in openings)
    return first, max((o for o in openings if o[0] == first), key=lambda o: o[3])[1]


def _per_tooth_day(channel: Any) -> tuple[np.ndarray, float, list[float]] | None:
    angle = channel.baseline_stats.get("tooth1_pitch_angle_deg")
    if not channel.teeth or angle is None:
        return None
    return (np.asarray(channel.curves["pinion_average"], dtype=np.float64), float(angle),
            [float(t.score) for t in channel.teeth])


def _delay_between(a: np.ndarray, b: np.ndarray) -> int:
    """Sample delay d maximising Σ a[n + d]·b[n] (a is b delayed by d)."""
    full = np.fft.irfft(np.fft.rfft(a) * np.conj(np.fft.rfft(b)), n=a.size)
    return int(np.argmax(full))


def _speed_study(noisy: np.ndarray, fs: float, spec: Spec, tach_result: Any, tl: Any) -> dict[str, float]:
    """The tach-less day's speed against the tach's, and the spectrum's family scores (study)."""
    from dsp.meshspectrum import pair_speed_scores

    out: dict[str, float] = {"tach_rpm": float(tach_result.speed_rpm), "tachless_rpm": float(tl.speed_rpm)}
    try:
        proposals, scores = pair_speed_scores(noisy, fs, spec.pinion_teeth, spec.gear_teeth,
                                              min_shaft_hz=10.0 / (noisy.size / fs))
    except Exception:
        return out
    order = np.argsort(scores)[::-1]
    best = proposals[order[0]]
    rivals = [i for i in order[1:] if abs(proposals[i] / best - 1) > 0.02]
    out["best_score"] = float(scores[order[0]])
    if rivals:
        out["rival_score"] = float(scores[rivals[0]])
        out["rival_ratio"] = float(proposals[rivals[0]] / best)
    return out


def run_campaign(spec: Spec, seconds: float, cache: Path, hint: bool = True,
                 simulator: str = "physics", random_start: bool = True) -> dict[str, Any]:
    days = (_simulate_days(spec, seconds, cache) if simulator == "physics"
            else _independent_days(spec, seconds, cache))
    fs = float(days[0]["fs"])
    with_tach, without = _campaigns(spec, float(days[0]["tooth1"]), fs, hint,
                                    float(days[0].get("rpm", 0.0)))
    params = AnalysisParameters(samples_per_mesh=32)
    rng = np.random.default_rng(spec.seed + 11)
    start_rng = np.random.default_rng(spec.seed + 13)
    rev_samples = int(2 * fs * 60.0 / (float(days[0].get("rpm", 0.0)) or NOMINAL_RPM))
    reference: ToothFrameReference | None = None
    tach_teeth: list[dict[int, float] | None] = []
    tl_teeth: list[dict[int, float] | None] = []
    tach_days: list[tuple[np.ndarray, float, list[float]] | None] = []  # product rules' inputs
    tl_days: list[tuple[np.ndarray, float, list[float]] | None] = []
    alignment: list[str] = []
    margins: list[float] = []
    reference_delay: int | None = None
    pulse_reference: float | None = None
    by_pulses: list[str] = []
    pulse_offsets: list[float] = []  # teeth, the campaign frame against the founding day's
    pulse_evidence: list[list[Any]] = []  # per entry of by_pulses: separation z, sector z, variation
    angles: list[list[Any]] = []  # per tach-less day: harmonic, drift pass, speed variation
    speeds: list[dict[str, float]] = []  # GW_SPEED_STUDY: the spectrum's speed against the tach's
    spm = params.samples_per_mesh
    n = spec.pinion_teeth * spm
    reasons: list[str] = []
    speed_ratios: list[float] = []  # per numbered tach-less day: its speed / the tach's
    for index, day in enumerate(days):
        acc = day["acc"].astype(np.float64)
        factor = spec.noise_ratio * float(np.clip(1 + rng.normal(0, 0.15), 0.6, 1.5))
        if "noise_added" in day:  # the independent generator adds its own
            factor = 0.0
        noisy = acc + factor * float(np.std(acc)) * rng.standard_normal(acc.size)
        tach = day["tach"].astype(np.float64)
        if random_start:  # the simulators start every day at the same angle: a real day does not
            crop = int(start_rng.integers(0, rev_samples))
            noisy, tach = noisy[crop:], tach[crop:]
        record = RecordData({"acc": noisy, "tach": tach}, fs)
        sha = f"seed{spec.seed}-day{index + 1}"
        try:
            tach_result = analyze_record(record, with_tach, params, input_sha256=sha)
        except RecordRejected:
            # the tach chain refuses the day (e.g. too few revolutions after the random crop of
            # a slow, drifting day): there is no truth to score the tach-less day against
            tach_teeth.append(None)
            tl_teeth.append(None)
            tach_days.append(None)
            tl_days.append(None)
            alignment.append(NO_TACH_TRUTH)
            continue
        tach_teeth.append({t.tooth: t.mci_depth for t in tach_result.channels[0].teeth})
        tach_days.append(_per_tooth_day(tach_result.channels[0]))
        tl: RecordAnalysis = analyze_record(
            RecordData({"acc": noisy}, fs), without, params, input_sha256=sha,
            tooth_frames={} if reference is None else {"acc": reference},
        )
        channel = tl.channels[0]
        frame = channel.tooth_frame
        tl_days.append(_per_tooth_day(channel))
        q = tl.quality.tachless or {}
        angles.append([q.get("harmonic"), q.get("line_followed_along_drift"),
                       None if not q else round(float(q["speed_variation"]), 4),
                       q.get("harmonic_disagreement_teeth")])
        if os.environ.get("GW_SPEED_STUDY"):
            speeds.append(_speed_study(noisy, fs, spec, tach_result, tl))
        if not channel.teeth:
            tl_teeth.append(None)
            alignment.append("refused" if frame.get("kind") == "refused" else "no-angle")
            reasons.append(frame.get("reason", ""))
            if "pinion" in frame:
                margins.append(frame["pinion"]["margin"])
            continue
        tl_teeth.append({t.tooth: t.mci_depth for t in channel.teeth})
        # a third truth: a frame can be consistent from day to day at a wrong speed (every day
        # at half of it, say) and still number nothing right
        speed_ratios.append(round(tl.speed_rpm / tach_result.speed_rpm, 4))
        angle = _campaign_frame_angle_rev(tach, RecordData({"acc": noisy}, fs), without, params, frame, n, q)
        if pulse_reference is None:
            pulse_reference = angle
        else:
            off_teeth = ((angle - pulse_reference + 0.5) % 1.0 - 0.5) * spec.pinion_teeth
            by_pulses.append("right" if abs(off_teeth) < 0.5 else "wrong")
            pulse_offsets.append(round(off_teeth, 2))
            pinion = frame.get("pinion") or {}
            pulse_evidence.append([pinion.get("separation_z"), pinion.get("sector_pattern_z"),
                                   None if not q else round(float(q["speed_variation"]), 4)])
        delay = _delay_between(channel.curves["pinion_average"].astype(np.float64),
                               tach_result.channels[0].curves["pinion_average"].astype(np.float64))
        if reference_delay is None:
            reference_delay = delay
            alignment.append("reference")
        else:
            off = (delay - reference_delay + n // 2) % n - n // 2
            alignment.append("right" if abs(off) < spm / 2 else "wrong")
            margins.append(frame["pinion"]["margin"])
        folded = fold_reference(reference, channel, sha)
        reference = folded or reference
    tach_day, tach_tooth = _first_alarm(tach_teeth)
    tl_day, tl_tooth_campaign = _first_alarm(tl_teeth)
    product_tach_day, product_tach_tooth = _product_first_alarm(tach_days, spec.pinion_teeth)
    product_tl_day, product_tl_tooth_campaign = _product_first_alarm(tl_days, spec.pinion_teeth)

    def in_tach_numbering(tooth: int | None) -> int | None:
        if tooth is None or reference_delay is None:
            return None
        # campaign tooth k's pitch angle (tooth 1 at 0° in a tach-less campaign frame) in the tach
        # frame: campaign sample m is tach sample m − delay
        angle = (tooth - 1) * 360.0 / spec.pinion_teeth - reference_delay * 360.0 / n
        return tooth_at_angle(angle % 360.0, spec.pinion_teeth, with_tach.rig.tooth1_pitch_angle_deg)

    tl_tooth = in_tach_numbering(tl_tooth_campaign)
    return {
        "seed": spec.seed, "simulator": simulator, "teeth": [spec.pinion_teeth, spec.gear_teeth],
        "noise_ratio": round(spec.noise_ratio, 2), "spall_tooth": spec.spall_tooth,
        "onset_day": spec.onset_day, "alignment": alignment, "alignment_by_pulses": by_pulses,
        "pulse_offsets_teeth": pulse_offsets, "pulse_evidence": pulse_evidence,
        "angles": angles, "speeds": speeds,
        "margins": margins,
        "tach_first_alarm": [tach_day, tach_tooth], "tachless_first_alarm": [tl_day, tl_tooth],
        "product_tach_first_alarm": [product_tach_day, product_tach_tooth],
        "product_tachless_first_alarm": [product_tl_day, in_tach_numbering(product_tl_tooth_campaign)],
        "reasons": [r for r in reasons if r],
        "speed_ratios": speed_ratios,
    }


REASON_KINDS = (
    ("ambiguous", "ambiguous tooth frame"), ("no match", "does not match the reference"),
    ("speed unconfirmed", "not confirmed by the revolutions"), ("no mesh line", "no mesh line"),
    ("band not clean", "not clean"),
)


def reason_counts(rows: list[dict[str, Any]]) -> dict[str, int]:
    """Refusals and no-angle days by kind of reason (which refusal costs the most)."""
    counts: dict[str, int] = {}
    for reason in (x for r in rows for x in r["reasons"]):
        kind = next((k for k, text in REASON_KINDS if text in reason), "other")
        counts[kind] = counts.get(kind, 0) + 1
    return counts


NO_TACH_TRUTH = "tach rejected"
"""A day the tach chain refuses (no truth to score the tach-less chain against): not scored."""


def _agreement(rows: list[dict[str, Any]], tach_key: str,
               tachless_key: str) -> tuple[int, int, int, int, int, int]:
    """Campaigns whose first alarms agree: (within a day, same tooth, tooth within one, both
    silent, tach chain on the spalled tooth, tach-less chain on the spalled tooth); both silent
    counts as agreeing."""
    same_day = same_tooth = near_tooth = both_silent = tach_right = tachless_right = 0
    for r in rows:
        (td, tt), (ld, lt) = r[tach_key], r[tachless_key]
        tach_right += tt == r["spall_tooth"] and td is not None and td >= r["onset_day"]
        tachless_right += lt == r["spall_tooth"] and ld is not None and ld >= r["onset_day"]
        if td is None and ld is None:
            both_silent += 1
            same_day += 1
            same_tooth += 1
            near_tooth += 1
            continue
        if td is not None and ld is not None and abs(td - ld) <= 1:
            same_day += 1
        if tt is not None and lt is not None:
            z = r["teeth"][0]
            distance = min((tt - lt) % z, (lt - tt) % z)
            same_tooth += distance == 0
            near_tooth += distance <= 1
    return same_day, same_tooth, near_tooth, both_silent, tach_right, tachless_right


WRONG_SPEED = 0.03
"""A numbered tach-less day whose speed is more than 3 % off the tach's is counted wrong
(``numbered_at_a_wrong_speed``): the speed drifts by less within a day, a wrong member of the
mesh-line family is off by a ratio of small integers."""


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    days = [a for r in rows for a in r["alignment"] if a not in ("reference", NO_TACH_TRUTH)]
    after_onset = [a for r in rows for d, a in enumerate(r["alignment"], start=1)
                   if d >= r["onset_day"] and a not in ("reference", NO_TACH_TRUTH)]
    right, wrong = days.count("right"), days.count("wrong")
    refused, no_angle = days.count("refused"), days.count("no-angle")
    by_pulses = [a for r in rows for a in r.get("alignment_by_pulses", [])]
    same_day, same_tooth, near_tooth, both_silent, _, _ = _agreement(
        rows, "tach_first_alarm", "tachless_first_alarm")
    product = _agreement(rows, "product_tach_first_alarm", "product_tachless_first_alarm")
    count = max(1, len(rows))
    aligned_days = max(1, right + wrong)
    return {
        "campaigns": len(rows), "days_scored": len(days), "right": right, "wrong": wrong,
        "refused": refused, "no_angle": no_angle,
        "right_by_pulses": by_pulses.count("right"), "wrong_by_pulses": by_pulses.count("wrong"),
        "right_or_refused_pct": 100.0 * (right + refused + no_angle) / max(1, len(days)),
        "wrong_pct_of_aligned": 100.0 * wrong / aligned_days,
        "first_alarm_within_1_day_pct": 100.0 * same_day / count,
        "same_tooth_pct": 100.0 * same_tooth / count,
        "tooth_within_1_pct": 100.0 * near_tooth / count,
        "both_silent": both_silent,
        "product_first_alarm_within_1_day_pct": 100.0 * product[0] / count,
        "product_same_tooth_pct": 100.0 * product[1] / count,
        "product_both_silent": product[3],
        "product_spall_tooth_tach": product[4],
        "product_spall_tooth_tachless": product[5],
        "spalled_days": len(after_onset),
        "spalled_right": after_onset.count("right"),
        "spalled_wrong": after_onset.count("wrong"),
        "spalled_refused": after_onset.count("refused") + after_onset.count("no-angle"),
        "reasons": reason_counts(rows),
        "numbered_at_a_wrong_speed": sum(abs(ratio - 1) > WRONG_SPEED for r in rows
                                         for ratio in r.get("speed_ratios", [])),
    }


def _seeds(text: str) -> list[int]:
    out: list[int] = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        out.extend(range(int(lo), int(hi or lo) + 1))
    return out


def main() -> int:
    global MAX_DRIFT
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", default=None, help="e.g. 2000-2019 (default: dev then held-out)")
    parser.add_argument("--days", type=int, default=8)
    parser.add_argument("--seconds", type=float, default=4.0)
    parser.add_argument("--cache", default=".bench-cache/tachless")
    parser.add_argument("--json", default=None)
    parser.add_argument("--no-hint", action="store_true", help="no nominal speed: find it in the spectrum")
    parser.add_argument("--no-guard", action="store_true",
                        help="with --no-hint: keep the tooth frame of a day whose speed came from the spectrum, "
                             "unchecked by its revolutions (study)")
    parser.add_argument("--same-start", action="store_true",
                        help="do not crop a random 0–2 pinion revolutions off each record's start "
                             "(the simulators start every day at the same shaft angle)")
    parser.add_argument("--simulator", choices=("physics", "indep"), default="physics",
                        help="physics: the project simulator; indep: physics.independent")
    parser.add_argument("--max-drift", type=float, default=MAX_DRIFT,
                        help="indep: in-record speed drift drawn in 0 … this (default 0.05)")
    args = parser.parse_args()
    MAX_DRIFT = args.max_drift
    if args.no_guard:
        import gearwatch.usecases.analyze as analyze_module
        from dsp.shaftperiod import PeriodCheck

        # the day keeps its frame whatever its revolutions say (study: how often wrong)
        analyze_module.check_shaft_period = lambda *_args, **_kw: PeriodCheck("", {}, {}, {})
    groups = ({"seeds": _seeds(args.seeds)} if args.seeds
              else {"development": list(DEV_SEEDS), "held-out": list(HELD_OUT_SEEDS)})
    cache = Path(args.cache)
    report: dict[str, Any] = {}
    started = time.perf_counter()
    for name, seeds in groups.items():
        rows = []
        for seed in seeds:
            row = run_campaign(campaign_spec(seed, args.days), args.seconds, cache, not args.no_hint,
                               args.simulator, not args.same_start)
            rows.append(row)
            print(json.dumps(row), flush=True)
        report[name] = {"summary": summarise(rows), "rows": rows}
    print(f"\n{'set':12s} {'camp':>4s} {'days':>4s} {'right':>5s} {'refused':>7s} {'no angle':>8s} "
          f"{'wrong':>5s} {'1st alarm ±1 d':>14s} {'same tooth':>10s} {'tooth ±1':>8s} {'both silent':>11s}")
    for name, block in report.items():
        s = block["summary"]
        print(f"{name:12s} {s['campaigns']:4d} {s['days_scored']:4d} {s['right']:5d} {s['refused']:7d} "
              f"{s['no_angle']:8d} {s['wrong']:5d} {s['first_alarm_within_1_day_pct']:13.0f}% "
              f"{s['same_tooth_pct']:9.0f}% {s['tooth_within_1_pct']:7.0f}% {s['both_silent']:11d}")
    for name, block in report.items():
        s = block["summary"]
        print(f"{name}: the default per-tooth rules (change + score): first alarm within a day of "
              f"the tach chain's {s['product_first_alarm_within_1_day_pct']:.0f} %, same tooth "
              f"{s['product_same_tooth_pct']:.0f} %, both silent {s['product_both_silent']}; first "
              f"alarm on the spalled tooth (on or after onset): tach {s['product_spall_tooth_tach']}, "
              f"tach-less {s['product_spall_tooth_tachless']} of {s['campaigns']}")
        print(f"{name}: aligned days by the pulses' truth (the tach's angle at the campaign frame's "
              f"sample 0): right {s['right_by_pulses']}, wrong {s['wrong_by_pulses']}; numbered at a "
              f"speed more than {WRONG_SPEED:.0%} off the tach's: {s['numbered_at_a_wrong_speed']}")
        print(f"{name}: days with the spall: {s['spalled_days']}, right {s['spalled_right']}, "
              f"refused/no angle {s['spalled_refused']}, wrong {s['spalled_wrong']}; "
              f"refusals by reason: {s['reasons']}")
    print(f"({time.perf_counter() - started:.0f} s, {os.cpu_count()} cpus)")
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=1), encoding="utf-8")
    return 0 if not math.isnan(0.0) else 1


if __name__ == "__main__":
    sys.exit(main())
