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
    parser.add_argument("--samples-per-mesh", type=int, default=64)
    parser.add_argument("--max-frequency-hz", type=float, default=None)
    parser.add_argument("--max-findings", type=int, default=4)
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
    parser.set_defaults(func=run)


def default_model(campaign: Any, sample_rate_hz: float) -> Any:
    """The simulator defaults with the manifest rig's tooth counts, tooth-1 angle and sample rate."""
    import dataclasses

    from physics.config import GearPairModel

    model = GearPairModel()
    rig = campaign.rig
    geometry = dataclasses.replace(
        model.geometry, pinion_teeth=rig.pinion_teeth, gear_teeth=rig.gear_teeth
    )
    tach = dataclasses.replace(model.tachometer, tooth1_pitch_angle_deg=rig.tooth1_pitch_angle_deg)
    acquisition = dataclasses.replace(model.acquisition, sample_rate_hz=sample_rate_hz)
    return model.replace(geometry=geometry, tachometer=tach, acquisition=acquisition)


def measured_record(path: str, campaign: Any, channel: str | None) -> Any:
    """Read a record and return a :class:`MeasuredRecord` of one accelerometer channel."""
    from gearwatch.errors import InputError
    from ingest.sources import read_record

    record_path = Path(path)
    if not record_path.is_file():
        raise InputError(f"{record_path}: no such record file")
    return measured_from_record(read_record(record_path, campaign), campaign, channel, str(record_path))


def measured_from_record(record: Any, campaign: Any, channel: str | None, source: str) -> Any:
    """The :class:`MeasuredRecord` of one accelerometer channel of an already-read record
    (:class:`ingest.types.RecordData`); ``source`` names the record in error messages."""
    import numpy as np

    from dsp.tach import TachometerError, pulse_times_from_waveform
    from gearwatch.errors import InputError
    from physics.reconcile import MeasuredRecord

    tach = campaign.tachometer
    if tach is None:
        raise InputError("the manifest has no [tachometer]: reconciliation needs a pinion reference")
    if tach.shaft != "pinion":
        raise InputError("reconcile needs the tachometer on the pinion shaft (hunting-period frame)")
    accelerometers = [c.name for c in campaign.accelerometer_channels]
    if not accelerometers:
        raise InputError("the manifest declares no accelerometer channel")
    name = channel or accelerometers[0]
    if name not in accelerometers:
        raise InputError(f"--channel {name!r} is not an accelerometer channel of the manifest")
    fs = float(record.sample_rate_hz)
    raw = np.asarray(record.channel(tach.channel), dtype=np.float64)
    try:
        pulses = pulse_times_from_waveform(raw, fs) if tach.kind == "pulses" else raw
    except (TachometerError, ValueError) as error:
        raise InputError(f"{source}: tachometer: {error}") from None
    signal = np.asarray(record.channel(name), dtype=np.float64)
    return MeasuredRecord(signal, fs, np.asarray(pulses, dtype=np.float64), tach.pulses_per_rev)


def run(args: argparse.Namespace) -> int:
    from gearwatch.commands.simulate import load_model
    from gearwatch.errors import InputError
    from ingest.manifest import load_manifest
    from physics.config import model_to_toml
    from physics.reconcile import CATALOGUE, DEFAULT_MECHANISMS, ReconcileOptions, reconcile
    from physics.reconcile.report import html_report

    campaign = load_manifest(args.campaign)
    if not (campaign.rig.pinion_teeth and campaign.rig.gear_teeth):
        raise InputError("reconcile needs rig.pinion_teeth and rig.gear_teeth in the manifest")
    measured = measured_record(args.record, campaign, args.channel)
    reference = measured_record(args.reference, campaign, args.channel) if args.reference else None
    if args.model:
        model = load_model(args.model)
        g = model.geometry
        if (g.pinion_teeth, g.gear_teeth) != (campaign.rig.pinion_teeth, campaign.rig.gear_teeth):
            raise InputError(f"{args.model}: tooth counts differ from the manifest's rig")
    else:
        model = default_model(campaign, measured.sample_rate_hz)
    mechanisms = DEFAULT_MECHANISMS
    if args.mechanisms:
        mechanisms = tuple(m.strip() for m in args.mechanisms.split(",") if m.strip())
        unknown = [m for m in mechanisms if m not in CATALOGUE]
        if unknown:
            raise InputError(
                f"--mechanisms: unknown or not fitted: {', '.join(unknown)} "
                f"(fitted: {', '.join(CATALOGUE)})"
            )
    if args.forward_oversampling is not None and args.forward_oversampling < 1:
        raise InputError("--forward-oversampling must be at least 1")
    if args.samples_per_mesh < 8:
        raise InputError("--samples-per-mesh must be at least 8")
    options = ReconcileOptions(
        samples_per_mesh=args.samples_per_mesh,
        max_frequency_hz=args.max_frequency_hz,
        mechanisms=mechanisms,
        max_findings=args.max_findings,
        forward_oversampling=args.forward_oversampling,
    )
    try:
        result = reconcile(measured, model, reference=reference, options=options)
    except ValueError as error:
        raise InputError(f"{args.record}: {error}") from None
    data = result.to_json()
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
    return 0


def print_summary(data: dict[str, Any]) -> None:
    base, final = data["baseline"], data["final"]
    print(
        f"status {data['status']}: χ²/dof {base['chi2_dof']} → {final['chi2_dof']} "
        f"(bounds {final['chi2_dof_bounds'][0]}..{final['chi2_dof_bounds'][1]}), "
        f"excess explained {final['excess_explained']}"
    )
    for m in data["mismatches"]:
        print(f"  mismatch {json.dumps(m)}")
    for f in data["findings"]:
        where = f" {f['wheel']}" if f["wheel"] else ""
        where += f" tooth {f['tooth']}" if f["tooth"] is not None else ""
        print(f"  finding {f['mechanism']}{where}: {json.dumps(f['parameters'])} ΔBIC {f['evidence']['delta_bic']}")
    for u in data["unresolved"]:
        print(f"  unresolved {json.dumps(u)}")
