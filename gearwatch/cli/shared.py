"""What several ``gearwatch`` commands share: option helpers, printing, serving.

Only light imports at module level: every command module imports this one while the parser is
built, and ``gearwatch --help`` must stay fast.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
from typing import Any

from gearwatch.floor.defaults import MIN_SAMPLES_PER_MESH, SAMPLES_PER_MESH
from gearwatch.floor.errors import InputError

PARAMETER_FLAGS = {
    "mci_form": "--mci-form",
    "samples_per_mesh": "--samples-per-mesh",
    "min_revolutions": "--min-revolutions",
    "max_speed_variation": "--max-speed-variation",
}


def add_common_arguments(parser: argparse.ArgumentParser) -> None:
    """Database, raw store and analysis parameter options shared by ``replay`` and ``watch``."""
    parser.add_argument(
        "--db",
        metavar="URL",
        help="SQLAlchemy database URL (default: $GEARWATCH_DATABASE_URL, else "
        "sqlite:///gearwatch.db in the working directory); migrated automatically",
    )
    parser.add_argument(
        "--raw-store",
        metavar="DIR",
        help="content-addressed raw file store (default: $GEARWATCH_RAW_STORE, else ./raw-store)",
    )
    add_parameter_arguments(parser)
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def add_parameter_arguments(parser: argparse.ArgumentParser) -> None:
    """Analysis parameter options (``--params FILE`` and the individual flags), shared by every
    command that runs the chain; read back with :func:`parameters_from_args`."""
    parser.add_argument(
        "--params",
        metavar="FILE",
        help="analysis parameters as a JSON or TOML table (names as in AnalysisParameters)",
    )
    parser.add_argument("--mci-form", choices=("robust", "literal"), default=None,
                        help="MCI form: robust (default, localises on zero-mean averages) or the "
                        "seed's literal form")
    parser.add_argument("--samples-per-mesh", type=int, default=None, help=f"default {SAMPLES_PER_MESH}")
    parser.add_argument("--min-revolutions", type=int, default=None, help="default 20")
    parser.add_argument("--max-speed-variation", type=float, default=None,
                        help="(max − min)/mean of the per-revolution speed, default 0.5")


def manifest_path(location: str | Path) -> Path:
    path = Path(location)
    if path.is_dir():
        path = path / "campaign.toml"
    if not path.is_file():
        raise InputError(f"{path}: no campaign manifest (campaign.toml) found")
    return path


def parameters_from_args(args: argparse.Namespace) -> Any:
    """``--params FILE`` overlaid with the individual flags."""
    from gearwatch.floor.results import AnalysisParameters

    values: dict[str, Any] = {}
    if getattr(args, "params", None):
        path = Path(args.params)
        try:
            text = path.read_text(encoding="utf-8")
            if path.suffix.lower() == ".toml":
                import tomllib

                values = dict(tomllib.loads(text))
            else:
                values = dict(json.loads(text))
        except (OSError, ValueError) as error:
            raise InputError(f"{path}: cannot read parameters: {error}") from None
    for name in PARAMETER_FLAGS:
        flag_value = getattr(args, name, None)
        if flag_value is not None:
            values[name] = flag_value
    try:
        params = AnalysisParameters.from_dict(values)
    except (TypeError, ValueError) as error:
        raise InputError(f"invalid analysis parameters: {error}") from None
    if params.samples_per_mesh < MIN_SAMPLES_PER_MESH:
        raise InputError(f"samples_per_mesh must be at least {MIN_SAMPLES_PER_MESH}")
    return params


def database_url(args: argparse.Namespace) -> str:
    from gearwatch.floor.settings import Settings

    return str(args.db or Settings().database_url)


def raw_store_root(args: argparse.Namespace) -> Path:
    from gearwatch.floor.settings import Settings

    return Path(args.raw_store) if args.raw_store else Path(Settings().raw_store)


def bus_options(pairs: list[str]) -> dict[str, Any]:
    """``["port=43113", "name=x"]`` → ``{"port": 43113, "name": "x"}`` (ints and floats converted)."""
    options: dict[str, Any] = {}
    for pair in pairs:
        key, sep, text = pair.partition("=")
        if not sep or not key:
            raise InputError(f"--bus-option {pair!r}: expected KEY=VALUE")
        value: Any = text
        for convert in (int, float):
            try:
                value = convert(text)
                break
            except ValueError:
                continue
        options[key.strip()] = value
    return options


def serve_api(host: str, port: int, *, database_url: str | None = None, workers: int = 1,
              log_level: str = "info") -> None:
    """Run the REST API and the dashboard with uvicorn until stopped."""
    import uvicorn

    if not 0 < port < 65536:
        raise InputError(f"--port {port}: not a TCP port")
    if workers < 1:
        raise InputError(f"--workers {workers}: must be at least 1")
    if database_url:
        # Through the environment, so that every uvicorn worker process sees it too.
        os.environ["GEARWATCH_DATABASE_URL"] = database_url
    uvicorn.run(
        "service.app:create_app",
        factory=True,
        host=host,
        port=port,
        workers=workers,
        log_level=log_level,
        server_header=False,  # no "server: uvicorn" (service.security adds the rest)
    )


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
    if quality.score is not None:
        print(
            f"data quality {quality.score:.2f} (synchronous-to-noise {quality.sync_to_noise_db:.1f} dB"
            f" per revolution; {quality.rejected_revolutions} revolution(s) rejected; "
            f"{quality.glitch_samples} glitch, {quality.dropout_samples} dropout, "
            f"{quality.clipped_samples} clipped sample(s) bridged)"
        )
    for name, reason in quality.refused_channels.items():
        print(f"channel {name} left out: {reason}")
    for channel in analysis.channels:
        print(f"\nchannel {channel.channel}")
        metrics = "  ".join(f"{k}={v:.3g}" for k, v in channel.metrics.items())
        print(f"  metrics: {metrics}")
        frame = channel.tooth_frame
        if frame.get("kind") in ("refused", "none"):
            print(f"  per-tooth results omitted: {frame.get('reason')}")
            continue
        if not channel.teeth:
            print("  (no tooth counts in the manifest: per-tooth results omitted)")
            continue
        if frame.get("kind") != "tachometer":
            print(f"  tooth frame: {frame.get('kind')} "
                  f"({frame.get('note') or 'reference ' + str(frame.get('reference_sha256', ''))[:16]})")
        print("  tooth  pitch°   MCI depth   diff energy   diff kurtosis")
        for tooth in channel.teeth:
            marker = "  ◀ worst" if tooth.tooth == channel.worst_tooth else ""
            print(
                f"  {tooth.tooth:5d}  {tooth.pitch_angle_deg:6.1f}  {tooth.mci_depth:10.3f}"
                f"  {tooth.diff_energy:12.3f}  {tooth.diff_kurtosis:14.3f}{marker}"
            )
        print(f"  worst tooth: {channel.worst_tooth}")
