"""Reconciliation speed (recording → report, one core) and the blinded score table.

    .venv/bin/python benchmarks/bench_reconcile.py                 # speed table, full options
    .venv/bin/python benchmarks/bench_reconcile.py --blinded 3     # + blinded run, 3 per class
    .venv/bin/python benchmarks/bench_reconcile.py --no-speed --blinded 200 --classes control \
        --jobs 2 --jsonl controls.jsonl                            # the ≥ 200-run control proof
    .venv/bin/python benchmarks/bench_reconcile.py --table-from controls.jsonl

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
from typing import Any

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


def _one_blinded(scenario: Any) -> dict[str, Any]:
    from physics.reconcile import ReconcileOptions, reconcile
    from physics.reconcile.scenarios import effect_snr, measured_of, score

    options = ReconcileOptions(samples_per_mesh=32, max_frequency_hz=4000.0, max_findings=3)
    t = time.perf_counter()
    measured = measured_of(scenario, seconds=5.0)
    result = reconcile(measured, scenario.fit_model, options=options)
    seconds = time.perf_counter() - t
    effect = effect_snr(scenario, measured, samples_per_mesh=32, max_frequency_hz=4000.0)
    row = score(scenario, result.to_json(), effect)
    row["findings"] = [f"{f.mechanism} {f.wheel or ''} {f.tooth or ''}".strip() for f in result.findings]
    row["seconds"] = round(seconds, 1)
    return row


def blinded(per_class: int, seed: int, classes: list[str], jobs: int, jsonl: str | None) -> None:
    """Draw, reconcile and grade; rows stream to stdout (and ``jsonl``), then the table."""
    import multiprocessing

    from physics.reconcile.scenarios import draw_scenarios, score_table

    scenarios = draw_scenarios(classes, per_class=per_class, seed=seed)
    rows = []
    sink = open(jsonl, "a", encoding="utf-8") if jsonl else None
    try:
        with multiprocessing.get_context("spawn").Pool(jobs) if jobs > 1 else _Serial() as pool:
            for row in pool.imap_unordered(_one_blinded, scenarios):
                rows.append(row)
                line = json.dumps(row)
                print(line, flush=True)
                if sink:
                    sink.write(line + "\n")
                    sink.flush()
    finally:
        if sink:
            sink.close()
    print(score_table(rows))


class _Serial:
    """``Pool`` stand-in for one job (no worker processes)."""

    def __enter__(self) -> _Serial:
        return self

    def __exit__(self, *exc: object) -> None:
        return None

    def imap_unordered(self, func: object, items: list[object]) -> object:
        return map(func, items)  # type: ignore[call-overload]


def table_from_jsonl(path: str) -> None:
    from physics.reconcile.scenarios import score_table

    rows = [json.loads(line) for line in Path(path).read_text(encoding="utf-8").splitlines() if line.strip()]
    print(score_table(rows))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seconds", type=float, default=12.0)
    parser.add_argument("--blinded", type=int, default=0, help="scenarios per class (0: skip)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--no-speed", action="store_true")
    parser.add_argument("--classes", default=",".join(_classes()), help="comma-separated scenario classes")
    parser.add_argument("--jobs", type=int, default=1, help="scenarios reconciled in parallel (processes)")
    parser.add_argument("--jsonl", help="append every graded row to this file as it finishes")
    parser.add_argument("--table-from", help="print the score table of a --jsonl file and stop")
    args = parser.parse_args()
    if args.table_from:
        table_from_jsonl(args.table_from)
        return
    if not args.no_speed:
        speed_table(args.seconds)
    if args.blinded:
        blinded(args.blinded, args.seed, args.classes.split(","), args.jobs, args.jsonl)


def _classes() -> tuple[str, ...]:
    from physics.reconcile.scenarios import CLASSES

    return CLASSES


if __name__ == "__main__":
    main()
