"""Benchmark: the whole per-record chain against a straightforward scipy version, same process.

    .venv/bin/python benchmarks/bench_chain.py [--seconds 60] [--sample-rate 20000] [--repeat 5]

Both chains run on the same known-answer synthetic record (:mod:`dsp.synthetic`: 20/21 teeth,
1000 rpm ± 1 % slow speed fluctuation, a spall on tooth 16, no noise so the error measures the
chain, not the noise) and share the tachometer edge detection, the difference signal, the metrics
and the per-tooth code. They differ where the straightforward version is the obvious one:

* resampling — ``scipy.interpolate.CubicSpline`` of the whole raw signal, evaluated at the
  angle-grid times (phase from a CubicSpline through the pulse times), once for the pinion grid and
  once for the gear grid; gearwatch's :func:`dsp.angle.angle_resample` once, both averages from it;
* MCI — one FFT + IFFT per window position; gearwatch's closed form with one batched FFT.

Printed: seconds per record (best of ``--repeat``), real-time factor (record seconds / chain
seconds), speed-up, and the accuracy of both against the exact synthetic pinion average and of the
MCI curves against each other. No assertion on time: this prints, it does not judge.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np
from scipy.interpolate import CubicSpline

from dsp.angle import angle_resample
from dsp.cepstrum import real_cepstrum
from dsp.mci import default_median_width, moving_cepstrum_integral
from dsp.metrics import gear_metrics
from dsp.synthetic import SyntheticRecord, synthetic_gear_record
from dsp.tach import analyze_tachometer, pulse_times_from_waveform
from dsp.teeth import per_tooth_difference_stats, per_tooth_well_depth, worst_tooth
from dsp.tsa import difference_signal, regular_signal, residual_signal, synchronous_average
from gearwatch.pipeline import analyze_record
from ingest.types import Campaign, ChannelConfig, RecordData, RigConfig, TachometerConfig

PINION_TEETH, GEAR_TEETH, SAMPLES_PER_MESH, TOOTH1_DEG, SPALL_TOOTH = 20, 21, 64, 337.4, 16


def straightforward_mci(average: np.ndarray, window: int, form: str) -> tuple[np.ndarray, np.ndarray]:
    """One FFT + IFFT per window position (window centred on the sample), then a circular median."""
    n = average.size
    raw = np.empty(n)
    scale = np.log(np.sqrt(window) * np.sqrt(np.mean(average**2)))
    for i in range(n):
        segment = np.take(average, np.arange(i - window // 2, i - window // 2 + window), mode="wrap")
        cepstrum = real_cepstrum(segment)
        raw[i] = cepstrum[1:].sum() if form == "literal" else scale - cepstrum[0]
    width = default_median_width(window)
    half = width // 2
    padded = np.concatenate((raw[-half:], raw, raw[:half]))
    filtered = np.array([np.median(padded[i : i + width]) for i in range(n)])
    return raw, filtered


def straightforward_chain(
    signal: np.ndarray, tach: np.ndarray, sample_rate_hz: float, form: str
) -> dict[str, object]:
    pulse_times = analyze_tachometer(pulse_times_from_waveform(tach, sample_rate_hz), 1).pulse_times_s
    time_s = np.arange(signal.size) / sample_rate_hz
    spline = CubicSpline(time_s, signal)
    phase_to_time = CubicSpline(np.arange(pulse_times.size, dtype=float), pulse_times)
    averages = {}
    for name, teeth, shaft_ratio in (
        ("pinion", PINION_TEETH, 1.0),
        ("gear", GEAR_TEETH, PINION_TEETH / GEAR_TEETH),
    ):
        samples_per_rev = teeth * SAMPLES_PER_MESH
        revs = int((pulse_times.size - 1) * shaft_ratio)
        grid_rev = np.arange(revs * samples_per_rev) / samples_per_rev  # target-shaft revolutions
        averages[name] = spline(phase_to_time(grid_rev / shaft_ratio)).reshape(revs, samples_per_rev).mean(0)
    average = averages["pinion"]
    difference = difference_signal(average, PINION_TEETH)
    _raw, filtered = straightforward_mci(average, SAMPLES_PER_MESH, form)
    depths = per_tooth_well_depth(filtered, PINION_TEETH, TOOTH1_DEG, window_samples=SAMPLES_PER_MESH)
    per_tooth_difference_stats(difference, PINION_TEETH, TOOTH1_DEG)
    gear_metrics(
        average, residual_signal(average, PINION_TEETH), difference,
        regular_signal(average, PINION_TEETH), PINION_TEETH,
    )
    return {"average": average, "mci": filtered, "worst_tooth": worst_tooth(depths),
            "revolutions": int(pulse_times.size - 1)}


def gearwatch_chain(record: RecordData, campaign: Campaign) -> dict[str, object]:
    channel = analyze_record(record, campaign, input_sha256="0" * 64).channels[0]
    return {
        "average": channel.curves["pinion_average"].astype(float),
        "mci": channel.curves["mci"].astype(float),
        "worst_tooth": channel.worst_tooth,
        "revolutions": channel.revolutions,
    }


def best_time(function: Callable[[], dict[str, object]], repeat: int) -> tuple[float, dict[str, object]]:
    best, result = np.inf, {}
    for _ in range(repeat):
        start = time.perf_counter()
        result = function()
        best = min(best, time.perf_counter() - start)
    return best, result


def relative_error(estimate: np.ndarray, truth: np.ndarray) -> float:
    return float(np.sqrt(np.mean((estimate - truth) ** 2) / np.mean(truth**2)))


def stage_times(synthetic: SyntheticRecord, repeat: int) -> dict[str, float]:
    """Where gearwatch's time goes (best of ``repeat`` per stage)."""
    fs, x = synthetic.sample_rate_hz, synthetic.acceleration
    spr = PINION_TEETH * SAMPLES_PER_MESH
    stages: dict[str, Callable[[], object]] = {}
    pulses = analyze_tachometer(pulse_times_from_waveform(synthetic.tach_waveform, fs), 1).pulse_times_s
    revs = angle_resample(x, fs, pulses, 1, spr)
    average = synchronous_average(revs)
    stages["tachometer"] = lambda: analyze_tachometer(pulse_times_from_waveform(synthetic.tach_waveform, fs), 1)
    stages["angle resampling"] = lambda: angle_resample(x, fs, pulses, 1, spr)
    stages["synchronous averages"] = lambda: synchronous_average(revs)
    stages["MCI (robust)"] = lambda: moving_cepstrum_integral(average, SAMPLES_PER_MESH)
    times = {}
    for name, stage in stages.items():
        best = np.inf
        for _ in range(repeat):
            start = time.perf_counter()
            stage()
            best = min(best, time.perf_counter() - start)
        times[name] = best
    return times


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--sample-rate", type=float, default=20_000.0)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()

    synthetic = synthetic_gear_record(
        duration_s=args.seconds, sample_rate_hz=args.sample_rate, pinion_teeth=PINION_TEETH,
        gear_teeth=GEAR_TEETH, spall_tooth=SPALL_TOOTH, spall_depth=0.1,
        tooth1_pitch_angle_deg=TOOTH1_DEG, noise_rms=0.0, seed=1,
    )
    campaign = Campaign(
        id="bench", description="", sample_rate_hz=args.sample_rate,
        rig=RigConfig(id="bench", pinion_teeth=PINION_TEETH, gear_teeth=GEAR_TEETH,
                      tooth1_pitch_angle_deg=TOOTH1_DEG),
        tachometer=TachometerConfig(channel="tach"),
        channels=(ChannelConfig("acc", "accelerometer"), ChannelConfig("tach", "tachometer")),
    )
    record = RecordData({"acc": synthetic.acceleration, "tach": synthetic.tach_waveform}, args.sample_rate)

    gearwatch_chain(record, campaign)  # warm-up: imports, numba compilation, caches
    ours_s, ours = best_time(lambda: gearwatch_chain(record, campaign), args.repeat)
    ref_s, ref = best_time(
        lambda: straightforward_chain(synthetic.acceleration, synthetic.tach_waveform, args.sample_rate, "robust"),
        max(1, args.repeat // 2),
    )
    # The exact average over the revolutions each chain averaged: it includes what is left of the
    # gear-shaft component over a number of pinion revolutions that is not whole hunting periods.
    spr = PINION_TEETH * SAMPLES_PER_MESH
    ours_err = relative_error(np.asarray(ours["average"]),
                              synthetic.true_pinion_average(spr, n_revs=int(ours["revolutions"])))
    ref_err = relative_error(np.asarray(ref["average"]),
                             synthetic.true_pinion_average(spr, n_revs=int(ref["revolutions"])))
    mci_gap = float(np.max(np.abs(np.asarray(ours["mci"]) - np.asarray(ref["mci"]))))

    print(f"per-record chain, {args.seconds:g} s record at {args.sample_rate:g} Hz, "
          f"{PINION_TEETH}/{GEAR_TEETH} teeth, {SAMPLES_PER_MESH} samples per mesh period, one process")
    print()
    print("| chain | s per record | real-time factor | pinion TSA rel. error | worst tooth |")
    print("|---|---|---|---|---|")
    print(f"| gearwatch | {ours_s:.4f} | {args.seconds / ours_s:,.0f}× | {ours_err:.2e} | {ours['worst_tooth']} |")
    print(f"| straightforward scipy | {ref_s:.4f} | {args.seconds / ref_s:,.0f}× | {ref_err:.2e} | {ref['worst_tooth']} |")
    print()
    print(f"speed-up: {ref_s / ours_s:.1f}×   accuracy ratio (reference error / gearwatch error): "
          f"{ref_err / ours_err:.2f}   max |MCI gearwatch − MCI reference|: {mci_gap:.2e} Np   "
          f"(spall on tooth {SPALL_TOOTH})")
    print()
    print("| gearwatch stage | ms |")
    print("|---|---|")
    for name, seconds in stage_times(synthetic, args.repeat).items():
        print(f"| {name} | {seconds * 1e3:.2f} |")


if __name__ == "__main__":
    main()
