"""Reconciliation speed (recording → report, one core) and the blinded score table.

    .venv/bin/python benchmarks/bench_reconcile.py                 # speed table, full options
    .venv/bin/python benchmarks/bench_reconcile.py --blinded 3     # + blinded run, 3 per class

Speed: each record is simulated (12 s, the campaign default), written to WAV, then timed from
reading the file to the JSON and the HTML report, with the default options (64 samples per
mesh, band up to 0.4 × fs, every fitted mechanism). Budget: ≤ 120 s per record.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def speed_table(seconds: float) -> None:
    import tomli_w

    from gearwatch.commands.reconcile import measured_record
    from ingest.manifest import load_manifest
    from physics.campaign import manifest_dict
    from physics.config import Spall
    from physics.reconcile import reconcile
    from physics.reconcile.report import html_report
    from physics.reconcile.scenarios import default_base
    from physics.recordio import write_record
    from physics.simulator import simulate

    base = default_base()
    cases = {
        "control": base,
        "pinion ecc 2 µm": base.replace(deviations=dataclasses.replace(base.deviations, pinion_eccentricity_um=2.0)),
        "spall pinion 7": base.replace(deviations=dataclasses.replace(base.deviations, spalls=[Spall(tooth=7, depth_um=8.0)])),
    }
    print(f"| record ({seconds:.0f} s) | total s | observable | calibration | selection | report | simulations | status | findings |")
    print("|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        manifest = manifest_dict(base, [{"file": "rec.wav", "taken_at": "2026-03-01T09:00:00Z"}], "bench", "bench")
        (Path(tmp) / "campaign.toml").write_text(tomli_w.dumps(manifest), encoding="utf-8")
        campaign = load_manifest(Path(tmp) / "campaign.toml", check_files=False)
        for label, truth in cases.items():
            sim = simulate(truth, seconds=seconds, seed=1)
            path = Path(tmp) / "rec.wav"
            write_record(path, sim.channels, sim.sample_rate_hz)
            t0 = time.perf_counter()
            measured = measured_record(str(path), campaign, None)
            result = reconcile(measured, base)
            t1 = time.perf_counter()
            page = html_report(result)
            json.dumps(result.to_json())
            t2 = time.perf_counter()
            tm = result.timings_s
            names = ", ".join(f"{f.mechanism} {f.wheel or ''} {f.tooth or ''}".strip() for f in result.findings) or "–"
            print(
                f"| {label} | {t2 - t0:.1f} | {tm['observable']:.1f} | {tm['base_calibration']:.1f} | "
                f"{tm['selection']:.1f} | {t2 - t1:.1f} | {result.simulations} | {result.status} | {names} |",
                flush=True,
            )
            del page


def blinded(per_class: int, seed: int) -> None:
    from physics.reconcile import ReconcileOptions, reconcile
    from physics.reconcile.scenarios import CLASSES, draw_scenarios, measured_of, score, score_table

    options = ReconcileOptions(samples_per_mesh=32, max_frequency_hz=4000.0, max_findings=3)
    rows = []
    for scenario in draw_scenarios(CLASSES, per_class=per_class, seed=seed):
        t = time.perf_counter()
        result = reconcile(measured_of(scenario, seconds=5.0), scenario.fit_model, options=options)
        row = score(scenario, result.to_json())
        rows.append(row)
        print(f"{scenario.id}: {json.dumps(row)} ({time.perf_counter() - t:.0f} s)", flush=True)
    print(score_table(rows))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seconds", type=float, default=12.0)
    parser.add_argument("--blinded", type=int, default=0, help="scenarios per class (0: skip)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--no-speed", action="store_true")
    args = parser.parse_args()
    if not args.no_speed:
        speed_table(args.seconds)
    if args.blinded:
        blinded(args.blinded, args.seed)


if __name__ == "__main__":
    main()
