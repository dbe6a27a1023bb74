"""``gearwatch analyze RECORD --campaign campaign.toml [--json]``: the chain on one record file."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from gearwatch.cli.shared import add_parameter_arguments, parameters_from_args, print_report


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
    parser.add_argument(
        "--reference", default=None, metavar="RECORD",
        help="without a tachometer: number the teeth in the frame of this reference record of the "
             "same campaign (its tooth fingerprint); default: the record's own frame, said so in "
             "tooth_frame",
    )
    add_parameter_arguments(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from gearwatch.floor.errors import InputError
    from gearwatch.usecases.analyze import analyze_file
    from ingest.manifest import load_manifest

    record_path = Path(args.record)
    if not record_path.is_file():
        raise InputError(f"{record_path}: no such record file")
    campaign = load_manifest(args.campaign)
    params = parameters_from_args(args)
    tooth_frames = None
    if args.reference is not None:
        tooth_frames = reference_frames(Path(args.reference), campaign, params)
    analysis = analyze_file(record_path, campaign, params, tooth_frames=tooth_frames)
    if args.json:
        json.dump(analysis.to_json(curves=args.curves), sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
    else:
        print_report(analysis)
    return 0


def reference_frames(path: Any, campaign: Any, params: Any) -> dict[str, Any]:
    """The tooth-frame references a reference record founds, per channel (tach or tach-less)."""
    from gearwatch.floor.errors import InputError
    from gearwatch.usecases.analyze import analyze_file
    from gearwatch.usecases.tachless import fold_reference

    if not path.is_file():
        raise InputError(f"{path}: no such reference record file")
    reference = analyze_file(path, campaign, params, tooth_frames={})
    frames = {}
    for channel in reference.channels:
        folded = fold_reference(None, channel, reference.provenance.input_sha256)
        if folded is not None:
            frames[channel.channel] = folded
    if not frames:
        raise InputError(
            f"{path}: the reference record gives no tooth fingerprint ({reference.quality.per_tooth or 'no teeth'})"
        )
    return frames
