"""``gearwatch analyze RECORD --campaign campaign.toml [--json]``: the chain on one record file."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from gearwatch.commands.replay import add_parameter_arguments


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "analyze",
        help="run the signal chain on one record file and print per-tooth results",
        description=(
            "Run tachometer → angle resampling → synchronous average → MCI and gear metrics "
            "on one record file described by a campaign manifest."
        ),
    )
    parser.add_argument("record", help="record file (WAV, CSV, NPZ, HDF5, TDMS, MAT, CAN log)")
    parser.add_argument("--campaign", required=True, help="campaign manifest (campaign.toml)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--curves", action="store_true", help="with --json: include the curves")
    add_parameter_arguments(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from gearwatch.commands.replay import parameters_from_args
    from gearwatch.errors import InputError
    from gearwatch.pipeline import analyze_file
    from ingest.manifest import load_manifest

    record_path = Path(args.record)
    if not record_path.is_file():
        raise InputError(f"{record_path}: no such record file")
    campaign = load_manifest(args.campaign)
    params = parameters_from_args(args)
    analysis = analyze_file(record_path, campaign, params)
    if args.json:
        json.dump(analysis.to_json(curves=args.curves), sys.stdout, indent=2)
        sys.stdout.write("\n")
    else:
        print_report(analysis)
    return 0


def print_report(analysis: Any) -> None:
    """Human-readable per-tooth table, one block per accelerometer channel."""
    provenance = analysis.provenance
    quality = analysis.quality
    print(
        f"record sha256 {provenance.input_sha256[:16]}…  code {provenance.code_version}  "
        f"MCI form {provenance.parameters['mci_form']}"
    )
    print(
        f"speed {analysis.speed_rpm:.1f} rpm (variation {quality.speed_variation:.2%}), "
        f"{analysis.revolutions} pinion revolutions, {analysis.samples_per_rev} samples/rev, "
        f"{len(quality.tach_repairs)} tach repair(s)"
    )
    for channel in analysis.channels:
        print(f"\nchannel {channel.channel}")
        metrics = "  ".join(f"{k}={v:.3g}" for k, v in channel.metrics.items())
        print(f"  metrics: {metrics}")
        if not channel.teeth:
            print("  (no tooth counts in the manifest: per-tooth results omitted)")
            continue
        print("  tooth  pitch°   MCI depth   diff energy   diff kurtosis")
        for tooth in channel.teeth:
            marker = "  ◀ worst" if tooth.tooth == channel.worst_tooth else ""
            print(
                f"  {tooth.tooth:5d}  {tooth.pitch_angle_deg:6.1f}  {tooth.mci_depth:10.3f}"
                f"  {tooth.diff_energy:12.3f}  {tooth.diff_kurtosis:14.3f}{marker}"
            )
        print(f"  worst tooth: {channel.worst_tooth}")
