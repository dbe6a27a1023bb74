"""Real-recording defects: the spall's MCI well before and after robust averaging, and speed drift.

Run: ``.venv/bin/python benchmarks/bench_robust.py [--seeds 3] [--seconds 6]``.

Records come from the gear-pair simulator (``physics/``: a 15 µm spall on pinion tooth 16, the
default 20/21 pair, noise 0.05 m/s²) and from the known-answer synthetic generator
(``dsp.synthetic``: spall amplitude 0.1 on tooth 16). Into each, one defect is injected at a
random time (seeded): a glitch sample (3e38, 1e30, or +30 × the record's RMS), two NaN samples, a
dropout (10 ms or 100 ms of zeros, 50 ms holding the last value), or a clipped burst (30 ms
overdriven 3× and held at the record's extreme).

*before* is the chain as it was: every revolution in a plain mean, no defect handling (a NaN
record was refused; shown as "refused"). *after* is :func:`gearwatch.usecases.analyze.analyze_record`.
Columns: the spalled tooth's MCI depth, the deepest other tooth, whether the spalled tooth is the
worst, revolutions rejected, and the quality score. Medians over seeds, and the count of seeds
where the spalled tooth was the worst.

Held out: the thresholds (glitch range ×5, outlier factor 4, floor 2 %) were set on the
synthetic seed 4 record of the tests; the simulator records (seeds 1000+) and synthetic seeds
2000+ used here were never looked at while setting them.

The independent generator (``physics.independent``, written by another engineer) injects its
own glitches, dropouts and clipping, and its own slow speed drift: a held-out check of both
the injection and the physics.

The drift part runs the simulator with a linear speed drift of 0 / 15 / 30 / 40 % of nominal over
the record (±20 % about the mean = 40 %) and with a ±20 % sinusoidal drift, and prints whether
it was analysed, the spalled tooth's depth and the quality score.
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Callable

import numpy as np

from dsp.angle import angle_resample
from dsp.mci import moving_cepstrum_integral
from dsp.synthetic import synthetic_gear_record
from dsp.tach import TachometerError, analyze_tachometer, pulse_times_from_waveform
from dsp.teeth import per_tooth_well_depth
from gearwatch.floor.campaign import (
    Campaign,
    ChannelConfig,
    RecordData,
    RigConfig,
    TachometerConfig,
)
from gearwatch.floor.errors import RecordRejected
from gearwatch.floor.results import AnalysisParameters
from gearwatch.usecases.analyze import analyze_record
from physics.config import Deviations, GearPairModel, Operating, Spall
from physics.simulator import simulate

SPALL_TOOTH = 16
PINION, GEAR = 20, 21

Defect = Callable[[np.ndarray, np.random.Generator, float], None]


def glitch(value: float | None) -> Defect:
    def inject(acc: np.ndarray, rng: np.random.Generator, fs: float) -> None:
        i = int(rng.integers(acc.size // 10, acc.size * 9 // 10))
        acc[i] = value if value is not None else acc[i] + 30 * float(np.std(acc))
    return inject


def nans(acc: np.ndarray, rng: np.random.Generator, fs: float) -> None:
    acc[rng.integers(acc.size // 10, acc.size * 9 // 10, 2)] = np.nan


def dropout(seconds: float, hold: bool = False) -> Defect:
    def inject(acc: np.ndarray, rng: np.random.Generator, fs: float) -> None:
        n = int(seconds * fs)
        i = int(rng.integers(acc.size // 10, acc.size * 9 // 10 - n))
        acc[i : i + n] = acc[i - 1] if hold else 0.0
    return inject


def clipped_burst(acc: np.ndarray, rng: np.random.Generator, fs: float) -> None:
    n = int(0.03 * fs)
    i = int(rng.integers(acc.size // 10, acc.size * 9 // 10 - n))
    top = float(np.max(np.abs(acc)))
    acc[i : i + n] = np.clip(3 * acc[i : i + n], -top, top)


DEFECTS: dict[str, Defect | None] = {
    "clean": None,
    "glitch 3e38": glitch(3e38),
    "glitch 1e30": glitch(1e30),
    "glitch +30 rms": glitch(None),
    "2 NaN samples": nans,
    "dropout 10 ms zeros": dropout(0.01),
    "dropout 100 ms zeros": dropout(0.1),
    "dropout 50 ms held": dropout(0.05, hold=True),
    "clipped burst 30 ms": clipped_burst,
}


@dataclasses.dataclass
class Source:
    acc: np.ndarray
    tach: np.ndarray
    fs: float
    tooth1_deg: float


def campaign(tooth1_deg: float, fs: float) -> Campaign:
    return Campaign(
        id="bench", description="",
        rig=RigConfig(id="rig", pinion_teeth=PINION, gear_teeth=GEAR,
                      tooth1_pitch_angle_deg=tooth1_deg),
        sample_rate_hz=fs,
        tachometer=TachometerConfig(channel="tach", kind="pulses", shaft="pinion", pulses_per_rev=1),
        channels=(ChannelConfig("acc", "accelerometer"), ChannelConfig("tach", "tachometer")),
    )


def simulated(seed: int, seconds: float, operating: Operating | None = None) -> Source:
    model = GearPairModel(deviations=Deviations(spalls=[Spall(tooth=SPALL_TOOTH, depth_um=15.0)]))
    if operating is not None:
        model = model.replace(operating=operating)
    result = simulate(model, seconds=seconds, seed=seed)
    return Source(result.channels["acc"], result.channels["tach"], result.sample_rate_hz,
                  result.tooth1_pitch_angle_deg)


def synthetic(seed: int, seconds: float) -> Source:
    rec = synthetic_gear_record(duration_s=seconds, spall_tooth=SPALL_TOOTH, spall_depth=0.1,
                                tooth1_pitch_angle_deg=337.4, seed=seed)
    return Source(rec.acceleration, rec.tach_waveform, rec.sample_rate_hz, 337.4)


def before(src: Source, acc: np.ndarray) -> np.ndarray | None:
    """The chain as it was: resample every revolution, plain mean, MCI, per-tooth depth."""
    if not np.all(np.isfinite(acc)):
        return None  # refused: NaN or inf samples
    pulses = analyze_tachometer(
        pulse_times_from_waveform(src.tach, src.fs), 1, max_speed_variation=0.10
    ).pulse_times_s
    revs = angle_resample(acc, src.fs, pulses, 1, PINION * 64)
    mci = moving_cepstrum_integral(revs.mean(axis=0), 64, form="robust")
    return per_tooth_well_depth(mci.filtered, PINION, src.tooth1_deg, window_samples=64)


def after(src: Source, acc: np.ndarray) -> tuple[np.ndarray, int, float] | None:
    record = RecordData({"acc": acc, "tach": src.tach}, src.fs, source="bench")
    try:
        analysis = analyze_record(record, campaign(src.tooth1_deg, src.fs), AnalysisParameters(),
                                  input_sha256="0" * 64)
    except RecordRejected:
        return None
    depths = np.array([t.mci_depth for t in analysis.channels[0].teeth])
    return depths, analysis.quality.rejected_revolutions, float(analysis.quality.score or 0.0)


def summary(depth_sets: list[np.ndarray | None]) -> str:
    done = [d for d in depth_sets if d is not None]
    if not done:
        return f"{'refused':>28s}"
    spall = np.median([d[SPALL_TOOTH - 1] for d in done])
    other = np.median([np.delete(d, SPALL_TOOTH - 1).max() for d in done])
    right = sum(int(np.argmax(d)) == SPALL_TOOTH - 1 for d in done)
    refused = len(depth_sets) - len(done)
    note = f" ({refused} refused)" if refused else ""
    return f"{spall:8.3f} {other:9.3f} {right:3d}/{len(depth_sets)}{note:>6s}"


def defect_table(name: str, make: Callable[[int], Source], seeds: list[int]) -> None:
    print(f"\n{name}: spalled tooth {SPALL_TOOTH}, seeds {seeds[0]}..{seeds[-1]} "
          "(depth in Np, medians over seeds)")
    head = f"{'spall':>8s} {'worst oth':>9s} {'right':>5s}"
    print(f"{'defect':24s} | before {head:>25s} | after {head:>25s} {'rej revs':>8s} {'score':>6s}")
    sources = [make(seed) for seed in seeds]
    for label, inject in DEFECTS.items():
        b, a, rejected, scores = [], [], [], []
        for seed, src in zip(seeds, sources, strict=True):
            acc = np.array(src.acc, dtype=np.float64)
            if inject is not None:
                inject(acc, np.random.default_rng(seed), src.fs)
            b.append(before(src, acc))
            out = after(src, acc)
            a.append(None if out is None else out[0])
            if out is not None:
                rejected.append(out[1])
                scores.append(out[2])
        rej = f"{np.median(rejected):8.1f}" if rejected else f"{'-':>8s}"
        score = f"{np.median(scores):6.3f}" if scores else f"{'-':>6s}"
        print(f"{label:24s} | {summary(b):>32s} | {summary(a):>31s} {rej} {score}")


def independent_table(seeds: list[int], seconds: float) -> None:
    """Held out, injected by someone else: the independent generator's own artefacts."""
    from physics.independent.generator import generate_record
    from physics.independent.model import Acquisition as IAcq
    from physics.independent.model import Artefacts, IndependentModel
    from physics.independent.model import Operating as IOp
    from physics.independent.model import Spall as ISpall

    print(f"\nindependent generator (physics.independent, its own artefact injection; 15 µm pit "
          f"on tooth {SPALL_TOOTH}, {seconds:g} s, seeds {seeds[0]}..{seeds[-1]})")
    head = f"{'spall':>8s} {'worst oth':>9s} {'right':>5s}"
    print(f"{'case':24s} | before {head:>25s} | after {head:>25s} {'rej revs':>8s} {'score':>6s}")
    cases = {
        "clean": (Artefacts(), IOp()),
        "1 glitch 3e38": (Artefacts(glitches=1, glitch_value=3e38), IOp()),
        "3 glitches 3e38": (Artefacts(glitches=3, glitch_value=3e38), IOp()),
        "3 glitches 1e30": (Artefacts(glitches=3, glitch_value=1e30), IOp()),
        "3 ADC spikes 20x peak": (Artefacts(glitches=3), IOp()),
        "3 ADC spikes 5x peak": (Artefacts(glitches=3, glitch_peak_ratio=5.0), IOp()),
        "1 dropout 20 ms": (Artefacts(dropouts=1), IOp()),
        "3 dropouts 20 ms": (Artefacts(dropouts=3), IOp()),
        "clipped at 0.9 of peak": (Artefacts(clip_fraction_of_peak=0.9), IOp()),
        "clipped at 0.7 of peak": (Artefacts(clip_fraction_of_peak=0.7), IOp()),
        "drift ±15 %": (Artefacts(), IOp(speed_drift_fraction=0.15)),
        "drift ±20 %": (Artefacts(), IOp(speed_drift_fraction=0.20)),
        "drift ±20 % + 2 spikes": (Artefacts(glitches=2), IOp(speed_drift_fraction=0.20)),
    }
    for label, (artefacts, operating) in cases.items():
        b, a, rejected, scores = [], [], [], []
        for seed in seeds:
            model = IndependentModel(
                spalls=(ISpall(tooth=SPALL_TOOTH, depth_um=15.0),), artefacts=artefacts,
                operating=operating, acquisition=IAcq(seconds=seconds),
            )
            rec = generate_record(model, seed=seed)
            camp = rec.campaign()
            src = Source(rec.channels["acc"], rec.channels["tach"], rec.sample_rate_hz,
                         camp.rig.tooth1_pitch_angle_deg)
            try:
                b.append(before(src, np.array(src.acc, dtype=np.float64)))
            except TachometerError:  # the old chain refused (speed drift > 10 %)
                b.append(None)
            try:
                analysis = analyze_record(rec.record_data(), camp, input_sha256="0" * 64)
            except RecordRejected:
                a.append(None)
                continue
            a.append(np.array([t.mci_depth for t in analysis.channels[0].teeth]))
            rejected.append(analysis.quality.rejected_revolutions)
            scores.append(float(analysis.quality.score or 0.0))
        rej = f"{np.median(rejected):8.1f}" if rejected else f"{'-':>8s}"
        score = f"{np.median(scores):6.3f}" if scores else f"{'-':>6s}"
        print(f"{label:24s} | {summary(b):>32s} | {summary(a):>31s} {rej} {score}")


def drift_table(seeds: list[int], seconds: float) -> None:
    print(f"\nspeed drift (simulator, {seconds:g} s, 15 µm spall on tooth {SPALL_TOOTH}, "
          f"seeds {seeds[0]}..{seeds[-1]}); before: refused above (max-min)/mean = 0.10")
    print(f"{'drift':34s} {'(max-min)/mean':>14s} {'spall':>8s} {'worst oth':>9s} {'right':>5s} "
          f"{'score':>6s}  outcome")
    cases = {
        "none": Operating(),
        "linear +15 % over the record": Operating(speed_drift_fraction=0.15),
        "linear +30 % (±15 %)": Operating(speed_drift_fraction=0.30),
        "linear +40 % (±20 %)": Operating(speed_drift_fraction=0.40),
        "sine ±20 %, 0.1 Hz": Operating(speed_fluctuation_fraction=0.2, speed_fluctuation_hz=0.1),
        "linear +70 % (±35 %)": Operating(speed_drift_fraction=0.70),
    }
    for label, operating in cases.items():
        depth_sets: list[np.ndarray | None] = []
        variations, scores, reasons = [], [], set()
        for seed in seeds:
            src = simulated(seed, seconds, operating)
            pulses = pulse_times_from_waveform(src.tach, src.fs)
            speed = 60.0 / np.diff(pulses)
            variations.append((speed.max() - speed.min()) / speed.mean())
            record = RecordData({"acc": src.acc, "tach": src.tach}, src.fs, source="bench")
            try:
                analysis = analyze_record(record, campaign(src.tooth1_deg, src.fs),
                                          input_sha256="0" * 64)
            except RecordRejected as error:
                depth_sets.append(None)
                reasons.add(str(error)[:70])
                continue
            depth_sets.append(np.array([t.mci_depth for t in analysis.channels[0].teeth]))
            scores.append(float(analysis.quality.score or 0.0))
        outcome = "analysed" if not reasons else "; ".join(sorted(reasons))
        score = f"{np.median(scores):6.3f}" if scores else f"{'-':>6s}"
        print(f"{label:34s} {np.median(variations):14.3f} {summary(depth_sets):>28s} {score}  "
              f"{outcome}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=6.0)
    parser.add_argument("--only", choices=("simulator", "synthetic", "independent", "drift"))
    args = parser.parse_args()
    run = {
        "simulator": lambda: defect_table("simulator", lambda s: simulated(s, args.seconds),
                                          list(range(1000, 1000 + args.seeds))),
        "synthetic": lambda: defect_table("synthetic", lambda s: synthetic(s, args.seconds),
                                          list(range(2000, 2000 + args.seeds))),
        "independent": lambda: independent_table(list(range(3000, 3000 + args.seeds)),
                                                 args.seconds),
        "drift": lambda: drift_table(list(range(1000, 1000 + args.seeds)), args.seconds),
    }
    for name, table in run.items():
        if args.only in (None, name):
            table()


if __name__ == "__main__":
    main()
