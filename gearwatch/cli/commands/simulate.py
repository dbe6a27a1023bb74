"""``gearwatch simulate OUT_FILE --model MODEL.toml [--seconds 12 --seed N]``: one simulated record."""

from __future__ import annotations

import argparse
from typing import Any


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "simulate",
        help="simulate one gear-pair record (WAV, HDF5 or TDMS)",
        description=(
            "Simulate the accelerometer(s) and tachometer of a spur pair with the six-DOF "
            "gear-pair model (docs/simulator.md). The format follows OUT_FILE's suffix: "
            ".wav, .h5/.hdf5 or .tdms. Without --model the CETIM-like defaults are used; "
            "--print-model prints the effective model as TOML (a template to edit)."
        ),
    )
    parser.add_argument("out_file", nargs="?", help="record to write (.wav, .h5, .hdf5, .tdms)")
    parser.add_argument("--model", help="model TOML (default: the built-in CETIM-like pair)")
    parser.add_argument("--seconds", type=float, default=12.0, help="record length (default 12)")
    parser.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    parser.add_argument(
        "--print-model", action="store_true", help="print the effective model TOML and exit"
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from gearwatch.floor.errors import InputError
    from gearwatch.usecases.simulated_campaign import load_model
    from physics.config import model_to_toml
    from physics.recordio import RecordWriteError, record_format, write_record
    from physics.simulator import simulate

    model = load_model(args.model)
    if args.print_model:
        print(model_to_toml(model), end="")
        return 0
    if not args.out_file:
        raise InputError("OUT_FILE is required (or use --print-model)")
    if not args.seconds > 0:
        raise InputError("--seconds must be > 0")
    try:
        record_format(args.out_file)
    except RecordWriteError as error:
        raise InputError(str(error)) from None
    try:
        result = simulate(model, seconds=args.seconds, seed=args.seed)
    except ValueError as error:  # SimulationError and bad lengths: input, not a bug
        raise InputError(f"{args.model or 'default model'}: {error}") from None
    path = write_record(args.out_file, result.channels, result.sample_rate_hz)
    names = ", ".join(result.channels)
    print(
        f"wrote {path} ({args.seconds:g} s at {result.sample_rate_hz:g} Hz; channels {names}; "
        f"tooth1_pitch_angle_deg = {result.tooth1_pitch_angle_deg:g})"
    )
    return 0
