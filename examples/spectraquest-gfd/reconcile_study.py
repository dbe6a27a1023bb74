"""SpectraQuest reconciliation study (issue 6): broken tooth vs healthy reference, per load.

The SpectraQuest records have no tachometer and no documented sampling rate. For each load
(h30hzNN healthy as reference, b30hzNN broken tooth as record) this script

1. derives once-per-revolution pulses of the 32-tooth shaft from the mesh phase
   (:mod:`dsp.tachless`), assuming 12.9 kHz (≈ 430 samples/rev at the nominal 30 Hz);
2. puts the broken record in the healthy record's angle frame: the synthetic origin is only
   defined up to whole mesh periods, so the record is shifted by the whole number of mesh
   periods (0 … 159, one hunting period of 32/80) that best correlates its hunting-period
   average with the reference's;
3. checks the tooth counts against the sidebands (32 on the tach shaft; the gear count from
   the gear-order sideband spacing);
4. runs ``physics.reconcile.reconcile(record, model, reference=healthy)`` with a 32/80
   :class:`GearPairModel`, and a control (healthy vs the healthy record of the next load);
5. prints plain indicators (residual kurtosis of the pinion and gear averages, worst-tooth MCI
   depth) healthy vs broken, independent of the reconciliation, and whether each shaft's
   tooth-specific pattern is the same in both records (:func:`shaft_matches`).

Run: ``python examples/spectraquest-gfd/reconcile_study.py [--loads 0,50,90] [--json OUT]``.
The data directory is ``$GEARWATCH_SHARED_DIR/data/real/spectraquest-gfd`` (default: the
``shared`` folder beside the repository). Results and their limits: docs/spectraquest-study.md.
"""

from __future__ import annotations

import argparse
import dataclasses
import gzip
import json
import math
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import CubicSpline

from dsp.angle import angle_resample
from dsp.mci import moving_cepstrum_integral
from dsp.metrics import kurtosis
from dsp.tachless import ShaftAngleEstimate, tachless_shaft_angle
from dsp.teeth import per_tooth_mci_depth
from dsp.tsa import residual_signal
from physics.config import GearPairModel
from physics.reconcile import MeasuredRecord, ReconcileOptions, ReconciliationResult, reconcile

FloatArray = NDArray[np.float64]

ASSUMED_SAMPLE_RATE_HZ = 12_900.0
"""Not documented by the source: 430 samples/rev × 30 Hz nominal. Angle-domain results do not
depend on it; the simulator's Hz-fixed content (the structural modes) and speeds in rpm do."""
SAMPLES_PER_REV_README = 430.0
PINION_TEETH = 32
"""Teeth on the shaft whose angle we estimate (the mesh line is order 32 of it)."""
GEAR_TEETH = 80
"""From the gear-order sidebands at 0.4 × the tach-shaft orders (checked by gear_teeth_scan)."""
LOADS = (0, 10, 20, 30, 40, 50, 60, 70, 80, 90)
CHANNEL = 0
"""a1; the mesh line is 30-34 dB above the floor on every channel, a1 is the first."""
STUDY_MECHANISMS = ("tooth_crack", "tooth_spall", "pinion_eccentricity", "gear_eccentricity")
"""Broken-tooth candidates and the two shaft effects; the index-error, mode, profile and load
scans are left out to keep one load ~1-2 min (each one-tooth scan simulates all 112 teeth one
by one: gcd(32, 80) = 16 rules out the mesh-delay shortcut)."""


def data_dir() -> Path:
    """``$GEARWATCH_SHARED_DIR/data/real/spectraquest-gfd``, default ``<repo>/../shared/...``."""
    shared = os.environ.get("GEARWATCH_SHARED_DIR")
    root = Path(shared) if shared else Path(__file__).resolve().parents[3] / "shared"
    return root / "data" / "real" / "spectraquest-gfd"


def load_signal(name: str, channel: int = CHANNEL, directory: Path | None = None) -> FloatArray:
    """One accelerometer column of ``<name>.csv.gz`` (header ``a1,a2,a3,a4``)."""
    path = (directory or data_dir()) / f"{name}.csv.gz"
    with gzip.open(path, "rt") as handle:
        table = np.loadtxt(handle, delimiter=",", skiprows=1)
    return np.asarray(table[:, channel], dtype=np.float64)


def study_model(sample_rate_hz: float = ASSUMED_SAMPLE_RATE_HZ) -> GearPairModel:
    """The simulator defaults with 32/80 teeth at the assumed sampling rate."""
    model = GearPairModel()
    geometry = dataclasses.replace(model.geometry, pinion_teeth=PINION_TEETH, gear_teeth=GEAR_TEETH)
    acquisition = dataclasses.replace(model.acquisition, sample_rate_hz=sample_rate_hz)
    return model.replace(geometry=geometry, acquisition=acquisition)


def study_options(max_findings: int = 2) -> ReconcileOptions:
    """16 angle samples per mesh period (the record has 13.4 time samples per mesh period, so
    nothing above it is lost), band to 0.4 × fs, 4 integrator steps per sample."""
    return ReconcileOptions(
        samples_per_mesh=16,
        mechanisms=STUDY_MECHANISMS,
        max_findings=max_findings,
        forward_oversampling=4,
    )


# ----------------------------------------------------------------------------- angle frame


def tachless_pulses(signal: FloatArray, sample_rate_hz: float = ASSUMED_SAMPLE_RATE_HZ) -> ShaftAngleEstimate:
    """Once-per-rev pulses of the 32-tooth shaft from mesh harmonic 1 (±0.3 orders)."""
    return tachless_shaft_angle(
        signal,
        sample_rate_hz,
        PINION_TEETH,
        approx_shaft_hz=sample_rate_hz / SAMPLES_PER_REV_README,
        harmonic=1,
        bandwidth_orders=0.3,
    )


def hunting_average(signal: FloatArray, sample_rate_hz: float, pulses: FloatArray, samples_per_mesh: int = 16) -> FloatArray:
    """Average over whole hunting periods (5 revolutions of the 32-tooth shaft for 32/80)."""
    revs_per_hunt = math.lcm(PINION_TEETH, GEAR_TEETH) // PINION_TEETH
    revs = angle_resample(signal, sample_rate_hz, pulses, 1, PINION_TEETH * samples_per_mesh)
    whole = revs.shape[0] // revs_per_hunt * revs_per_hunt
    hunts = revs[:whole].reshape(whole // revs_per_hunt, -1)
    return np.asarray(hunts.mean(axis=0), dtype=np.float64)


def shift_pulses(pulses: FloatArray, revolutions: float) -> FloatArray:
    """Pulses moved by a constant shaft angle (``revolutions``, may be fractional), by a cubic
    spline of time against revolution count; pulses past the end are dropped."""
    spline = CubicSpline(np.arange(pulses.size, dtype=float), pulses)
    count = np.arange(pulses.size, dtype=float) + revolutions
    count = count[(count >= 0) & (count <= pulses.size - 1)]
    return np.asarray(spline(count), dtype=np.float64)


@dataclass(frozen=True)
class Alignment:
    mesh_periods: int
    """Mesh periods (0 … 159) by which the record's origin was moved."""
    correlation: float
    """Correlation of the aligned hunting-period averages."""
    runner_up: float
    """Best correlation at any other shift (the margin says how sure the frame is)."""


def align_to_reference(
    signal: FloatArray, pulses: FloatArray, ref_average: FloatArray, sample_rate_hz: float, samples_per_mesh: int = 16
) -> tuple[FloatArray, Alignment]:
    """Move the record's origin by the whole number of mesh periods that best correlates its
    hunting-period average with the reference's (circular cross-correlation)."""
    average = hunting_average(signal, sample_rate_hz, pulses, samples_per_mesh)
    a = (average - average.mean()) / np.linalg.norm(average - average.mean())
    b = (ref_average - ref_average.mean()) / np.linalg.norm(ref_average - ref_average.mean())
    # c[s] = Σ_n b[n] a[n + s]: the record sampled from s onwards matches the reference.
    corr = np.fft.irfft(np.conj(np.fft.rfft(b)) * np.fft.rfft(a), n=a.size)
    per_mesh = corr[::samples_per_mesh]
    best = int(np.argmax(per_mesh))
    others = np.delete(per_mesh, best)
    shifted = shift_pulses(pulses, best / PINION_TEETH)
    return shifted, Alignment(best, float(per_mesh[best]), float(others.max()))


@dataclass(frozen=True)
class ShaftMatch:
    correlation: float
    """Best correlation of the two records' residual averages of one shaft over whole-tooth shifts."""
    shift_teeth: int
    runner_up: float


def shaft_matches(
    signal: FloatArray, pulses: FloatArray, ref_signal: FloatArray, ref_pulses: FloatArray, sample_rate_hz: float
) -> dict[str, ShaftMatch]:
    """Does each shaft look the same in both records? Per shaft (32-tooth "pinion", 80-tooth
    "gear"): the synchronous average with its mesh harmonics removed (the tooth-specific
    content: runout, tooth-to-tooth differences), correlated over all whole-tooth shifts."""
    out = {}
    for wheel, teeth, ratio in (("pinion", PINION_TEETH, 1.0), ("gear", GEAR_TEETH, PINION_TEETH / GEAR_TEETH)):
        spr = teeth * 16
        averages = []
        for x, p in ((signal, pulses), (ref_signal, ref_pulses)):
            average = angle_resample(x, sample_rate_hz, p, 1, spr, shaft_ratio=ratio).mean(axis=0)
            residual = residual_signal(average, teeth)
            residual = residual - residual.mean()
            averages.append(residual / np.linalg.norm(residual))
        a, b = averages
        corr = np.fft.irfft(np.conj(np.fft.rfft(b)) * np.fft.rfft(a), n=spr)[::16]
        best = int(np.argmax(corr))
        out[wheel] = ShaftMatch(float(corr[best]), best, float(np.delete(corr, best).max()))
    return out


def worst_tooth_across_loads(condition: str, loads: tuple[int, ...] = LOADS) -> dict[str, list[tuple[int, float]]]:
    """Per shaft, the tooth with the most residual energy at every load, all loads in the frame
    of the load-0 record of the same condition ("h" or "b"), with its robust z-score
    ((max − median) / (1.4826 MAD) of the per-tooth RMS). A damaged tooth would stay the
    same tooth across loads; tooth numbers are relative to the load-0 record's origin."""
    base = load_signal(f"{condition}30hz{loads[0]}")
    base_pulses = tachless_pulses(base).pulse_times_s
    signals = {load: load_signal(f"{condition}30hz{load}") for load in loads}
    pulses = {load: tachless_pulses(x).pulse_times_s for load, x in signals.items()}
    out: dict[str, list[tuple[int, float]]] = {}
    for wheel, teeth, ratio in (("pinion", PINION_TEETH, 1.0), ("gear", GEAR_TEETH, PINION_TEETH / GEAR_TEETH)):
        spr = teeth * 16
        ref = residual_signal(angle_resample(base, ASSUMED_SAMPLE_RATE_HZ, base_pulses, 1, spr, shaft_ratio=ratio).mean(axis=0), teeth)
        rows = []
        for load in loads:
            revs = angle_resample(signals[load], ASSUMED_SAMPLE_RATE_HZ, pulses[load], 1, spr, shaft_ratio=ratio)
            residual = residual_signal(revs.mean(axis=0), teeth)
            corr = np.fft.irfft(np.conj(np.fft.rfft(ref)) * np.fft.rfft(residual), n=spr)[::16]
            residual = np.roll(residual, -16 * int(np.argmax(corr)))  # into the load-0 frame
            energy = np.sqrt((residual.reshape(teeth, 16) ** 2).mean(axis=1))
            mad = 1.4826 * float(np.median(np.abs(energy - np.median(energy))))
            rows.append((int(np.argmax(energy)) + 1, float((energy.max() - np.median(energy)) / mad)))
        out[wheel] = rows
    return out


# ----------------------------------------------------------------------------- tooth counts


def gear_teeth_scan(
    signal: FloatArray, sample_rate_hz: float, pulses: FloatArray, candidates: range = range(70, 91)
) -> dict[int, float]:
    """For each candidate gear tooth count, the fraction of the order spectrum's energy near the
    mesh harmonics (±3 orders) that sits on its gear-order sidebands ``h·32 ± j·32/Z``
    (j = 1, 2), from an order spectrum over all whole revolutions (resolution 1/revs)."""
    samples_per_rev = PINION_TEETH * 16
    revs = angle_resample(signal, sample_rate_hz, pulses, 1, samples_per_rev)
    flat = revs.reshape(-1)
    spectrum = np.abs(np.fft.rfft(flat * np.hanning(flat.size))) ** 2
    n_revs = revs.shape[0]
    orders = np.arange(spectrum.size) / n_revs
    near = np.zeros(spectrum.size, dtype=bool)
    for h in range(1, 6):
        near |= np.abs(orders - h * PINION_TEETH) <= 3.0
    near &= ~np.isclose(orders % 1.0, 0.0, atol=0.5 / n_revs) & ~np.isclose(orders % 1.0, 1.0, atol=0.5 / n_revs)
    total = float(spectrum[near].sum())
    out = {}
    for z in candidates:
        hit = np.zeros(spectrum.size, dtype=bool)
        for h in range(1, 6):
            for j in (-2, -1, 1, 2):
                target = h * PINION_TEETH + j * PINION_TEETH / z
                hit |= np.abs(orders - target) <= 1.0 / n_revs
        out[z] = float(spectrum[hit & near].sum() / total)
    return out


# ----------------------------------------------------------------------------- indicators


def plain_indicators(signal: FloatArray, sample_rate_hz: float, pulses: FloatArray) -> dict[str, float]:
    """Residual kurtosis of the pinion (32 teeth) and gear (80 teeth) averages and the worst
    pinion tooth by MCI depth (tooth numbers relative to the synthetic origin)."""
    pinion_spr, gear_spr = PINION_TEETH * 16, GEAR_TEETH * 16
    pinion = angle_resample(signal, sample_rate_hz, pulses, 1, pinion_spr).mean(axis=0)
    gear = angle_resample(
        signal, sample_rate_hz, pulses, 1, gear_spr, shaft_ratio=PINION_TEETH / GEAR_TEETH
    ).mean(axis=0)
    mci = moving_cepstrum_integral(pinion, 16)
    depth = per_tooth_mci_depth(mci.filtered, PINION_TEETH, 0.0)
    return {
        "pinion_residual_kurtosis": float(kurtosis(residual_signal(pinion, PINION_TEETH))),
        "gear_residual_kurtosis": float(kurtosis(residual_signal(gear, GEAR_TEETH))),
        "pinion_worst_tooth_mci": int(np.argmax(depth)) + 1,
        "pinion_worst_mci_depth_np": float(np.max(depth)),
    }


# ----------------------------------------------------------------------------- one pair


@dataclass
class PairResult:
    record: str
    reference: str
    record_pulses: ShaftAngleEstimate
    reference_pulses: ShaftAngleEstimate
    alignment: Alignment
    result: ReconciliationResult | None
    indicators: dict[str, dict[str, float]] = field(default_factory=dict)
    shaft_match: dict[str, ShaftMatch] = field(default_factory=dict)
    seconds: float = 0.0

    def summary(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "record": self.record,
            "reference": self.reference,
            "samples_per_rev": {
                self.record: 1.0 / self.record_pulses.mean_shaft_hz * ASSUMED_SAMPLE_RATE_HZ,
                self.reference: 1.0 / self.reference_pulses.mean_shaft_hz * ASSUMED_SAMPLE_RATE_HZ,
            },
            "mesh_line_db": [self.record_pulses.line_prominence_db, self.reference_pulses.line_prominence_db],
            "alignment": dataclasses.asdict(self.alignment),
            "shaft_match": {k: dataclasses.asdict(v) for k, v in self.shaft_match.items()},
            "indicators": self.indicators,
            "seconds": self.seconds,
        }
        if self.result is not None:
            data = self.result.to_json()
            out.update(
                {
                    "status": data["status"],
                    "baseline_chi2_dof": data["baseline"]["chi2_dof"],
                    "final_chi2_dof": data["final"]["chi2_dof"],
                    "chi2_dof_bounds": data["final"]["chi2_dof_bounds"],
                    "excess_explained": data["final"]["excess_explained"],
                    "misfit": [data["baseline"]["misfit"], data["final"]["misfit"]],
                    "findings": data["findings"],
                    "mismatches": data["mismatches"],
                    "reference_fit": data["reference"],
                    "unresolved": data["unresolved"],
                    "hunting_periods": data["record"]["hunting_periods"],
                    "top_candidates": self.result.candidates_scored,
                }
            )
        return out


def study_pair(
    record_signal: FloatArray,
    reference_signal: FloatArray,
    *,
    record: str = "record",
    reference: str = "reference",
    sample_rate_hz: float = ASSUMED_SAMPLE_RATE_HZ,
    options: ReconcileOptions | None = None,
    run_reconcile: bool = True,
) -> PairResult:
    """Tach-less pulses for both records, the record aligned to the reference's frame, plain
    indicators, and (``run_reconcile``) the reference-relative reconciliation."""
    t0 = time.perf_counter()
    ref_est = tachless_pulses(reference_signal, sample_rate_hz)
    rec_est = tachless_pulses(record_signal, sample_rate_hz)
    ref_average = hunting_average(reference_signal, sample_rate_hz, ref_est.pulse_times_s)
    rec_pulses, alignment = align_to_reference(record_signal, rec_est.pulse_times_s, ref_average, sample_rate_hz)
    indicators = {
        reference: plain_indicators(reference_signal, sample_rate_hz, ref_est.pulse_times_s),
        record: plain_indicators(record_signal, sample_rate_hz, rec_pulses),
    }
    match = shaft_matches(record_signal, rec_pulses, reference_signal, ref_est.pulse_times_s, sample_rate_hz)
    result = None
    if run_reconcile:
        result = reconcile(
            MeasuredRecord(record_signal, sample_rate_hz, rec_pulses, 1),
            study_model(sample_rate_hz),
            reference=MeasuredRecord(reference_signal, sample_rate_hz, ref_est.pulse_times_s, 1),
            options=options or study_options(),
        )
    return PairResult(
        record=record,
        reference=reference,
        record_pulses=dataclasses.replace(rec_est, pulse_times_s=rec_pulses),
        reference_pulses=ref_est,
        alignment=alignment,
        result=result,
        indicators=indicators,
        shaft_match=match,
        seconds=time.perf_counter() - t0,
    )


def _finding_text(f: dict[str, Any]) -> str:
    where = f" {f['wheel']}" if f.get("wheel") else ""
    where += f" tooth {f['tooth']}" if f.get("tooth") is not None else ""
    params = ", ".join(f"{k} {v}" for k, v in f["parameters"].items())
    return f"{f['mechanism']}{where} ({params}; ΔBIC {f['evidence'].get('delta_bic')})"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--loads", default=",".join(str(x) for x in LOADS))
    parser.add_argument("--json", dest="json_out", help="write every pair's summary here")
    parser.add_argument("--max-findings", type=int, default=2)
    parser.add_argument(
        "--controls",
        default="0:10",
        help="same-condition controls REF:REC[,REF:REC...] (loads), run healthy and broken; '' for none",
    )
    parser.add_argument("--teeth", action="store_true", help="print worst_tooth_across_loads and stop")
    args = parser.parse_args(argv)
    loads = [int(x) for x in args.loads.split(",") if x.strip()]
    controls = [tuple(int(v) for v in c.split(":")) for c in args.controls.split(",") if c.strip()]
    directory = data_dir()
    if not directory.is_dir():
        print(f"no data directory {directory} (set GEARWATCH_SHARED_DIR)", file=sys.stderr)
        return 2
    if args.teeth:
        for condition in ("h", "b"):
            for wheel, rows in worst_tooth_across_loads(condition).items():
                cells = " ".join(f"{tooth}({z:.1f})" for tooth, z in rows)
                print(f"{condition}30hz* {wheel}: worst tooth (z) at loads {LOADS}: {cells}")
        return 0
    options = study_options(args.max_findings)
    rows = []
    for load in loads:
        healthy, broken = f"h30hz{load}", f"b30hz{load}"
        pair = study_pair(load_signal(broken), load_signal(healthy), record=broken, reference=healthy, options=options)
        rows.append(pair.summary())
        _print_row(rows[-1])
    # Controls: the same gearbox at another load (healthy vs healthy, broken vs broken).
    for ref_load, rec_load in controls:
        for condition in ("h", "b"):
            ref, rec = f"{condition}30hz{ref_load}", f"{condition}30hz{rec_load}"
            pair = study_pair(load_signal(rec), load_signal(ref), record=rec, reference=ref, options=options)
            summary = pair.summary()
            summary["control"] = True
            rows.append(summary)
            _print_row(summary)
    if args.json_out:
        Path(args.json_out).write_text(json.dumps(rows, indent=1, default=float) + "\n", encoding="utf-8")
    return 0


def _print_row(row: dict[str, Any]) -> None:
    findings = "; ".join(_finding_text(f) for f in row.get("findings", [])) or "–"
    ind = row["indicators"]
    print(
        f"{row['record']} vs {row['reference']}: {row.get('status')} χ²/dof {row.get('baseline_chi2_dof')} → "
        f"{row.get('final_chi2_dof')} (bounds {row.get('chi2_dof_bounds')}), excess explained "
        f"{row.get('excess_explained')}, align {row['alignment']}, {row['seconds']:.0f} s\n"
        f"    shaft match: {json.dumps(row['shaft_match'])}\n"
        f"    findings: {findings}\n"
        f"    mismatches: {json.dumps(row.get('mismatches'))}\n"
        f"    top candidates: {json.dumps(row.get('top_candidates'))}\n"
        f"    indicators: {json.dumps(ind)}",
        flush=True,
    )


if __name__ == "__main__":
    raise SystemExit(main())
