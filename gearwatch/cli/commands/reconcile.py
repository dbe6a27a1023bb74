"""``gearwatch reconcile RECORD --campaign campaign.toml``: simulation vs recording (issue 6).

Locate the mismatch between the simulator configuration and the record, name and fit the
missing physics from the catalogue, and report the fit before and after (JSON, HTML) and
optionally the configuration with the accepted findings added (``--write-model``).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from gearwatch.floor.defaults import RECONCILE_MAX_FINDINGS, SAMPLES_PER_MESH


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "reconcile",
        help="locate and explain the mismatch between the simulator and a record",
        description=(
            "Calibrate the simulator configuration (MODEL.toml, default: the manifest rig's "
            "default model) on the record, locate the residual (orders, teeth, band), explain it "
            "with the mechanism catalogue by forward selection, and report whether the final fit "
            "is within the noise (docs/reconciliation.md)."
        ),
    )
    parser.add_argument("record", help="record file described by the manifest")
    parser.add_argument("--campaign", required=True, help="campaign manifest (campaign.toml)")
    parser.add_argument("--model", help="simulator configuration TOML (gearwatch simulate --print-model)")
    parser.add_argument("--reference", help="healthy reference record of the same rig")
    parser.add_argument("--json", dest="json_out", help="write the JSON result here ('-': stdout)")
    parser.add_argument("--report", help="write the HTML report here")
    parser.add_argument("--write-model", help="write the configuration with the accepted findings")
    parser.add_argument("--channel", help="accelerometer channel (default: the manifest's first)")
    parser.add_argument("--samples-per-mesh", type=int, default=SAMPLES_PER_MESH)
    parser.add_argument("--max-frequency-hz", type=float, default=None)
    parser.add_argument("--max-findings", type=int, default=RECONCILE_MAX_FINDINGS)
    parser.add_argument(
        "--forward-oversampling",
        type=int,
        default=None,
        help="integrator steps per sample of the fitting simulations (default: the model's)",
    )
    parser.add_argument(
        "--mechanisms",
        help="comma-separated catalogue names to try (default: every fitted plug-in but "
        "speed_fluctuation, see docs/reconciliation.md)",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress on stderr")
    parser.set_defaults(func=run)


RECONCILE_STAGES = (
    "reading the manifest",
    "reading the records, simulator in the loop (minutes)",
    "writing results",
)


def run(args: argparse.Namespace) -> int:
    from gearwatch.cli.progress import StageProgress
    from ingest.manifest import load_manifest
    from physics.config import model_to_toml
    from physics.reconcile.report import html_report

    with StageProgress(f"reconcile {Path(args.record).name}", RECONCILE_STAGES,
                       enabled=not args.no_progress) as progress:
        progress.stage(RECONCILE_STAGES[0])
        campaign = load_manifest(args.campaign)
        result = _reconcile(args, campaign, progress)
        progress.stage(RECONCILE_STAGES[2])
        _write(args, result, html_report, model_to_toml)
    return 0


def _reconcile(args: argparse.Namespace, campaign: Any, progress: Any) -> Any:
    from gearwatch.usecases.reconcile import ReconcileRequest, reconcile_file
    from gearwatch.usecases.simulated_campaign import load_model

    mechanisms = None
    if args.mechanisms:
        mechanisms = tuple(m.strip() for m in args.mechanisms.split(",") if m.strip())
    request = ReconcileRequest(
        channel=args.channel,
        mechanisms=mechanisms,
        samples_per_mesh=args.samples_per_mesh,
        max_frequency_hz=args.max_frequency_hz,
        max_findings=args.max_findings,
        forward_oversampling=args.forward_oversampling,
    )
    progress.stage(RECONCILE_STAGES[1])

    def inner(stage: str, fraction: float) -> None:
        # The reconciliation's own stage and fraction (physics.reconcile.progress) in the bar.
        progress.stage(f"{stage} {100.0 * fraction:.0f} %")

    return reconcile_file(
        args.record, campaign, request,
        model=load_model(args.model) if args.model else None, model_name=str(args.model),
        reference=args.reference, progress=inner,
    )


def _write(args: argparse.Namespace, result: Any, html_report: Any, model_to_toml: Any) -> None:
    from gearwatch.floor.results import finite_json

    data = finite_json(result.to_json())  # strict JSON: no NaN tokens
    if args.json_out == "-":
        json.dump(data, sys.stdout, indent=2)
        sys.stdout.write("\n")
    elif args.json_out:
        Path(args.json_out).write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
    if args.report:
        Path(args.report).write_text(html_report(result, title=f"reconcile {args.record}"), encoding="utf-8")
    if args.write_model:
        Path(args.write_model).write_text(model_to_toml(result.updated_model), encoding="utf-8")
    if args.json_out != "-":
        print_summary(data)


def print_summary(data: dict[str, Any]) -> None:
    base, final = data["baseline"], data["final"]
    print(
        f"status {data['status']}: χ²/dof {base['chi2_dof']} → {final['chi2_dof']} "
        f"(bounds {final['chi2_dof_bounds'][0]}..{final['chi2_dof_bounds'][1]}), "
        f"excess explained {final['excess_explained']}"
    )
    form_error = base.get("mesh_line_form_error") or 0.0
    if form_error > 0:
        print(f"  the configured mesh model misses this record's mesh lines by {form_error:.0%} "
              "(declared as their uncertainty; see model_form.mesh_line_form_error)")
    for m in data["mismatches"]:
        print(f"  mismatch {json.dumps(m)}")
    for f in data["findings"]:
        where = f" {f['wheel']}" if f["wheel"] else ""
        where += f" tooth {f['tooth']}" if f["tooth"] is not None else ""
        print(f"  finding {f['mechanism']}{where}: {json.dumps(f['parameters'])} ΔBIC {f['evidence']['delta_bic']}")
    for u in data["unresolved"]:
        print(f"  unresolved {json.dumps(u)}")
