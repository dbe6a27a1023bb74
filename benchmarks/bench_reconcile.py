"""Reconciliation speed (recording → report, one core) and the blinded score table.

    .venv/bin/python benchmarks/bench_reconcile.py                 # speed table, full options
    .venv/bin/python benchmarks/bench_reconcile.py --cases strong  # one speed case (substring)
    .venv/bin/python benchmarks/bench_reconcile.py --blinded 3     # + blinded run, 3 per class
    .venv/bin/python benchmarks/bench_reconcile.py --no-speed --blinded 200 --classes control \
        --jobs 2 --jsonl controls.jsonl                            # the ≥ 200-run control proof
    .venv/bin/python benchmarks/bench_reconcile.py --table-from controls.jsonl

Speed: each record is simulated (24 s), written to WAV, then timed in CPU seconds from reading
the file to the JSON and the HTML report, with the default options (64 samples per mesh, band up
to 0.4 × fs, the default scan). Budget (issue 15): ≤ 120 s of CPU per record including a
reference (met since 2026-11-27: 22 / 65 / 36 s, docs/reconciliation.md). CPU seconds of the same
code move between sessions by a quarter: compare two versions only back to back, with
``nice -n 5`` on a shared machine.
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
from typing import Any, TextIO

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def _keep_row(row: dict[str, Any], rows: list[dict[str, Any]], sink: TextIO | None) -> None:
    """Collect one scenario's row, print it as a JSON line, and append it to the JSONL sink."""
    rows.append(row)
    line = json.dumps(row)
    print(line, flush=True)
    if sink:
        sink.write(line + "\n")
        sink.flush()


def speed_table(seconds: float, only: list[str] | None = None) -> None:
    """CPU seconds (this process, one core) from the record file to the JSON and HTML report.

    Issue 15's budget: ≤ 120 s of CPU per 24 s record including a reference. Cases: a control;
    a strong spall (25 µm on pinion tooth 16, over 9 mm of the face and 3 mm of the profile —
    a shape the catalogue's default spall does not have) reconciled with a healthy reference
    of the same rig; a weak effect (a 1.5 µm pinion runout, below the raw noise). The truths are
    the project's simulator with base parameters perturbed within tolerance and a finer
    integration step (as in the blinded run).
    """
    import numpy as np
    import tomli_w

    from gearwatch.usecases.reconcile import measured_record
    from ingest.manifest import load_manifest
    from physics.campaign import manifest_dict
    from physics.config import Spall
    from physics.reconcile import reconcile
    from physics.reconcile.report import html_report
    from physics.reconcile.scenarios import _perturbed, default_base
    from physics.recordio import write_record
    from physics.simulator import simulate

    base = default_base()
    rig = _perturbed(base, np.random.default_rng(5))
    wide = Spall(wheel="pinion", tooth=16, depth_um=25.0, profile_start_mm=-1.0, profile_extent_mm=3.0,
                 face_start_mm=4.0, face_width_mm=9.0)
    cases = {
        "control": (rig, None),
        "strong spall 25 µm + reference": (
            rig.replace(deviations=dataclasses.replace(rig.deviations, spalls=[wide])), rig),
        "weak: pinion runout 1.5 µm": (
            rig.replace(deviations=dataclasses.replace(rig.deviations, pinion_eccentricity_um=1.5,
                                                        pinion_eccentricity_phase_deg=40.0)), None),
    }
    print(f"| record ({seconds:.0f} s) | CPU s | wall s | reference | calibration | selection | simulations "
          "| status | findings | defects |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        manifest = manifest_dict(base, [{"file": "rec.wav", "taken_at": "2026-03-01T09:00:00Z"}], "bench", "bench")
        (Path(tmp) / "campaign.toml").write_text(tomli_w.dumps(manifest), encoding="utf-8")
        campaign = load_manifest(Path(tmp) / "campaign.toml", check_files=False)
        for label, (truth, healthy) in cases.items():
            if only and not any(o in label for o in only):
                continue
            paths = []
            for name, model, seed in (("rec.wav", truth, 1), ("ref.wav", healthy, 2)):
                if model is None:
                    continue
                sim = simulate(model, seconds=seconds, seed=seed)
                write_record(Path(tmp) / name, sim.channels, sim.sample_rate_hz)
                paths.append(Path(tmp) / name)
            c0, t0 = time.process_time(), time.perf_counter()
            measured = measured_record(str(paths[0]), campaign, None)
            reference = measured_record(str(paths[1]), campaign, None) if len(paths) > 1 else None
            result = reconcile(measured, base, reference=reference)
            page = html_report(result)
            data = result.to_json()
            json.dumps(data)
            cpu, wall = time.process_time() - c0, time.perf_counter() - t0
            tm = result.timings_s
            names = ", ".join(f"{f.mechanism} {f.wheel or ''} {f.tooth or ''}".strip() for f in result.findings) or "–"
            defects = "; ".join(d["place"] + " " + d["like"] for d in data["model_form"]["defects"]) or "–"
            print(
                f"| {label} | {cpu:.0f} | {wall:.0f} | {tm.get('reference', 0.0):.0f} | {tm['base_calibration']:.0f} | "
                f"{tm['selection']:.0f} | {result.simulations} | {result.status} | {names} | {defects} |",
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
    rows: list[dict[str, Any]] = []
    sink = open(jsonl, "a", encoding="utf-8") if jsonl else None
    try:
        with multiprocessing.get_context("spawn").Pool(jobs) if jobs > 1 else _Serial() as pool:
            for row in pool.imap_unordered(_one_blinded, scenarios):
                _keep_row(row, rows, sink)
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


def _one_independent(args: tuple[str, int]) -> dict[str, Any]:
    import numpy as np

    from physics.reconcile import ReconcileOptions, reconcile
    from physics.reconcile.scenarios import (
        draw_independent,
        measured_of_independent,
        score_independent,
    )

    klass, seed = args
    scenario = draw_independent(klass, np.random.default_rng(seed), seed)
    measured = measured_of_independent(scenario)
    c0 = time.process_time()
    result = reconcile(measured, scenario.fit_model,
                       options=ReconcileOptions(samples_per_mesh=32, max_frequency_hz=4000.0, max_findings=3))
    row = score_independent(scenario, result.to_json())
    row["cpu_s"] = round(time.process_time() - c0, 1)
    row["seed"] = seed
    return row


def independent(per_class: int, seed: int, classes: list[str], jsonl: str | None) -> None:
    """Blinded run with the independent truth generator (physics.independent), interleaved by
    class so that a run cut short still covers every class; seeds ``seed … seed + per_class − 1``."""
    rows: list[dict[str, Any]] = []
    sink = open(jsonl, "a", encoding="utf-8") if jsonl else None
    try:
        for i in range(per_class):
            for klass in classes:
                _keep_row(_one_independent((klass, seed + i)), rows, sink)
    finally:
        if sink:
            sink.close()
    print(independent_table(rows))


def independent_table(rows: list[dict[str, Any]]) -> str:
    """Per-class summary of independent-truth rows (Markdown)."""
    import math

    lines = ["| class | runs | right mech+place first | right place first | absent mechanism named "
             "| false findings (controls) | friction stated not separable | 95 % interval covers truth "
             "| median CPU s |", "|---|---|---|---|---|---|---|---|---|"]
    for klass in dict.fromkeys(r["class"] for r in rows):
        rs = [r for r in rows if r["class"] == klass]

        def frac(key: str, rs: list[dict[str, Any]] = rs) -> str:
            vals = [bool(r[key]) for r in rs if key in r]
            return f"{sum(vals)}/{len(vals)}" if vals else "–"

        cpu = sorted(float(r["cpu_s"]) for r in rs)
        med = cpu[len(cpu) // 2] if cpu else math.nan
        lines.append(f"| {klass} | {len(rs)} | {frac('right_mechanism_and_place_first')} | "
                     f"{frac('right_place_first')} | {frac('absent_mechanism_named')} | {frac('false_finding')} | "
                     f"{frac('friction_stated_not_separable')} | {frac('covered')} | {med:.0f} |")
    return "\n".join(lines)


def table_from_jsonl(path: str) -> None:
    from physics.reconcile.scenarios import score_table

    rows = [json.loads(line) for line in Path(path).read_text(encoding="utf-8").splitlines() if line.strip()]
    indep = [r for r in rows if str(r.get("class", "")).startswith("indep_")]
    if indep:
        print(independent_table(indep))
    rest = [r for r in rows if r not in indep]
    if rest:
        print(score_table(rest))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seconds", type=float, default=24.0)
    parser.add_argument("--cases", help="comma-separated substrings of the speed cases to run")
    parser.add_argument("--blinded", type=int, default=0, help="scenarios per class (0: skip)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--no-speed", action="store_true")
    parser.add_argument("--classes", default=",".join(_classes()), help="comma-separated scenario classes")
    parser.add_argument("--jobs", type=int, default=1, help="scenarios reconciled in parallel (processes)")
    parser.add_argument("--jsonl", help="append every graded row to this file as it finishes")
    parser.add_argument("--table-from", help="print the score table of a --jsonl file and stop")
    parser.add_argument("--independent", type=int, default=0,
                        help="blinded runs per class with the independent truth generator (0: skip)")
    args = parser.parse_args()
    if args.table_from:
        table_from_jsonl(args.table_from)
        return
    if not args.no_speed:
        speed_table(args.seconds, args.cases.split(",") if args.cases else None)
    if args.independent:
        from physics.reconcile.scenarios import INDEPENDENT_CLASSES

        chosen = [c for c in args.classes.split(",") if c in INDEPENDENT_CLASSES] or list(INDEPENDENT_CLASSES)
        independent(args.independent, args.seed, chosen, args.jsonl)
    if args.blinded:
        blinded(args.blinded, args.seed, args.classes.split(","), args.jobs, args.jsonl)


def _classes() -> tuple[str, ...]:
    from physics.reconcile.scenarios import CLASSES

    return CLASSES


if __name__ == "__main__":
    main()
