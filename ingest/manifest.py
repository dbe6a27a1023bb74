"""Campaign manifest (``campaign.toml``): strict parsing, validation and TOML output.

The format is documented in the README. Parsing is strict: an unknown key, a
missing required key, a value of the wrong type, a tachometer channel not declared in
``[[channels]]`` or a record file that does not exist raises
:class:`gearwatch.floor.errors.ManifestError` whose message names the manifest file and the
key (``[rig] pinion_teeth``, ``[[records]][2] file``) or the missing file.

``[tachometer]`` may be omitted (a rig without a tach, such as the SpectraQuest data):
the pipeline then takes the shaft angle from the mesh phase when ``[rig]`` gives the tooth
counts (``nominal_pinion_rpm`` is an optional speed hint), and otherwise keeps the
whole-record raw metrics only (:mod:`gearwatch.usecases.tachless`).

Example
-------
>>> from pathlib import Path
>>> campaign = parse_manifest(
...     {
...         "campaign": {"id": "demo"},
...         "rig": {"id": "rig-1"},
...         "tachometer": {"channel": "tach"},
...         "channels": [
...             {"name": "acc", "kind": "accelerometer"},
...             {"name": "tach", "kind": "tachometer"},
...         ],
...     },
...     root=Path("."),
... )
>>> [c.name for c in campaign.accelerometer_channels]
['acc']
>>> parse_manifest(tomllib.loads(dump_manifest(campaign)), root=Path(".")) == campaign
True
"""

from __future__ import annotations

import datetime as dt
import math
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any, NoReturn, cast, get_args

import tomli_w

from gearwatch.floor.campaign import (
    Campaign,
    ChannelConfig,
    ChannelKind,
    RecordEntry,
    RigConfig,
    Shaft,
    TachEdge,
    TachKind,
    TachometerConfig,
)
from gearwatch.floor.errors import ManifestError, RecordRejected

__all__ = ["dump_manifest", "load_manifest", "parse_manifest", "require_tachometer"]

_TOP_LEVEL_KEYS = ("campaign", "rig", "acquisition", "tachometer", "channels", "records")
_CAMPAIGN_KEYS = ("id", "description")
_RIG_KEYS = ("id", "pinion_teeth", "gear_teeth", "tooth1_pitch_angle_deg", "nominal_pinion_rpm")
_ACQUISITION_KEYS = ("sample_rate_hz",)
_TACHOMETER_KEYS = ("channel", "kind", "shaft", "pulses_per_rev", "edge")
_CHANNEL_KEYS = ("name", "kind", "unit")
_RECORD_KEYS = ("file", "taken_at", "label")

# Bounds: what a real rig can have, and what the chain and the database can hold. A manifest
# outside them is refused naming the key (pinion_teeth = 100000 would hang the averaging,
# 1 or 2 teeth leave no order between mesh sidebands, a 5000-character file name fails the
# file system or the database column).
INTEGER_BOUNDS: dict[str, tuple[int, int]] = {
    "pinion_teeth": (3, 500),
    "gear_teeth": (3, 500),
    "pulses_per_rev": (1, 10_000),
}
NUMBER_BOUNDS: dict[str, tuple[float, float]] = {
    "sample_rate_hz": (1.0, 10_000_000.0),
    "nominal_pinion_rpm": (0.1, 1_000_000.0),
}
MAX_TEXT_LENGTH: dict[str, int] = {
    "id": 200, "description": 10_000, "name": 200, "unit": 32, "channel": 200,
    "file": 500, "label": 200, "kind": 32, "shaft": 32,
}
MAX_FILE_NAME_COMPONENT = 255
"""The longest file or folder name common file systems allow."""
MAX_CHANNELS = 64
MAX_RECORDS = 100_000


class _Context:
    """Where the manifest came from, to prefix every error message."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, where: str, message: str) -> NoReturn:
        raise ManifestError(f"{self.source}: {where}: {message}")


def load_manifest(path: str | Path, *, check_files: bool = True) -> Campaign:
    """Read and validate a ``campaign.toml``; record paths are relative to its folder.

    Raises :class:`ManifestError` naming the file and the offending key, or the record
    file that does not exist (``check_files=False`` skips that check, e.g. for a
    manifest uploaded before its records).
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ManifestError(f"{path}: manifest file not found") from None
    except (OSError, UnicodeDecodeError) as error:
        raise ManifestError(f"{path}: cannot read manifest: {error}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise ManifestError(f"{path}: not valid TOML: {error}") from None
    return parse_manifest(data, root=path.resolve().parent, source=str(path), check_files=check_files)


def parse_manifest(
    data: Mapping[str, Any],
    *,
    root: Path,
    source: str | None = None,
    check_files: bool = True,
) -> Campaign:
    """Validate a manifest already parsed from TOML (or JSON) into a :class:`Campaign`.

    ``root`` is the folder record paths are relative to; ``source`` names the manifest
    in error messages (default: ``<root>/campaign.toml``).
    """
    root = Path(root)
    ctx = _Context(source or str(root / "campaign.toml"))
    if not isinstance(data, Mapping):
        ctx.fail("manifest", f"must be a table, got {_type_name(data)}")
    _reject_unknown(ctx, "manifest", data, _TOP_LEVEL_KEYS, top_level=True)

    campaign_table = _table(ctx, data, "campaign", required=True)
    _reject_unknown(ctx, "[campaign]", campaign_table, _CAMPAIGN_KEYS)
    campaign_id = _string(ctx, "[campaign]", campaign_table, "id", required=True, nonempty=True)
    description = _string(ctx, "[campaign]", campaign_table, "description") or ""

    rig = _parse_rig(ctx, _table(ctx, data, "rig", required=True))

    acquisition = _table(ctx, data, "acquisition", required=False)
    _reject_unknown(ctx, "[acquisition]", acquisition, _ACQUISITION_KEYS)
    sample_rate_hz = _positive_number(ctx, "[acquisition]", acquisition, "sample_rate_hz")

    channels = _parse_channels(ctx, data.get("channels"))
    tachometer = _parse_tachometer(ctx, data, channels)
    records = _parse_records(ctx, data.get("records"), root, check_files)

    return Campaign(
        id=cast(str, campaign_id),
        description=description,
        rig=rig,
        sample_rate_hz=sample_rate_hz,
        tachometer=tachometer,
        channels=channels,
        records=records,
        root=root,
    )


def dump_manifest(campaign: Campaign) -> str:
    """The campaign as ``campaign.toml`` text; ``parse_manifest`` of it gives it back.

    Optional values that are unset (no tooth counts, no manifest sample rate, no
    tachometer) are left out, since TOML has no null. ``root`` is not written: it is
    the folder the manifest is saved in.
    """
    document: dict[str, Any] = {
        "campaign": {"id": campaign.id, "description": campaign.description},
    }
    rig: dict[str, Any] = {"id": campaign.rig.id}
    if campaign.rig.pinion_teeth is not None:
        rig["pinion_teeth"] = campaign.rig.pinion_teeth
    if campaign.rig.gear_teeth is not None:
        rig["gear_teeth"] = campaign.rig.gear_teeth
    rig["tooth1_pitch_angle_deg"] = float(campaign.rig.tooth1_pitch_angle_deg)
    if campaign.rig.nominal_pinion_rpm is not None:
        rig["nominal_pinion_rpm"] = _toml_number(campaign.rig.nominal_pinion_rpm)
    document["rig"] = rig
    if campaign.sample_rate_hz is not None:
        document["acquisition"] = {"sample_rate_hz": _toml_number(campaign.sample_rate_hz)}
    if campaign.tachometer is not None:
        tach = campaign.tachometer
        document["tachometer"] = {
            "channel": tach.channel,
            "kind": tach.kind,
            "shaft": tach.shaft,
            "pulses_per_rev": tach.pulses_per_rev,
            **({"edge": tach.edge} if tach.edge != "rising" else {}),  # the default unwritten
        }
    document["channels"] = [
        {"name": c.name, "kind": c.kind, "unit": c.unit} for c in campaign.channels
    ]
    if campaign.records:
        document["records"] = [
            {"file": r.file, "taken_at": r.taken_at, "label": r.label} for r in campaign.records
        ]
    return tomli_w.dumps(document)


def require_tachometer(campaign: Campaign) -> TachometerConfig:
    """The campaign's tachometer, or :class:`RecordRejected` explaining why there is none.

    A manifest without ``[tachometer]`` is valid (its records can be read and looked
    at) but per-revolution processing needs the shaft angle, so such records are
    rejected rather than analysed with a guessed speed.
    """
    if campaign.tachometer is None:
        raise RecordRejected(
            f"campaign {campaign.id!r} has no [tachometer]: shaft-angle resampling and "
            "per-revolution averaging are impossible without a tachometer"
        )
    return campaign.tachometer


# --- sections -------------------------------------------------------------------------


def _parse_rig(ctx: _Context, table: Mapping[str, Any]) -> RigConfig:
    _reject_unknown(ctx, "[rig]", table, _RIG_KEYS)
    rig_id = _string(ctx, "[rig]", table, "id", required=True, nonempty=True)
    pinion_teeth = _positive_int(ctx, "[rig]", table, "pinion_teeth")
    gear_teeth = _positive_int(ctx, "[rig]", table, "gear_teeth")
    if (pinion_teeth is None) != (gear_teeth is None):
        ctx.fail(
            "[rig]",
            "pinion_teeth and gear_teeth go together: give both, or neither "
            "(then per-tooth results are omitted)",
        )
    angle = table.get("tooth1_pitch_angle_deg", 0.0)
    if not _is_number(angle) or not math.isfinite(angle):
        ctx.fail("[rig] tooth1_pitch_angle_deg", f"must be a finite number, got {angle!r}")
    if not 0.0 <= float(angle) < 360.0:
        ctx.fail("[rig] tooth1_pitch_angle_deg", f"must be in [0, 360), got {angle!r}")
    return RigConfig(
        id=cast(str, rig_id),
        pinion_teeth=pinion_teeth,
        gear_teeth=gear_teeth,
        tooth1_pitch_angle_deg=float(angle),
        nominal_pinion_rpm=_positive_number(ctx, "[rig]", table, "nominal_pinion_rpm"),
    )


def _parse_channels(ctx: _Context, value: Any) -> tuple[ChannelConfig, ...]:
    if value is None:
        ctx.fail("[[channels]]", "missing: declare at least one accelerometer channel")
    if not isinstance(value, list):
        ctx.fail("channels", f"must be an array of tables [[channels]], got {_type_name(value)}")
    if len(value) > MAX_CHANNELS:
        ctx.fail("[[channels]]", f"{len(value)} channels, at most {MAX_CHANNELS} allowed")
    channels: list[ChannelConfig] = []
    seen: set[str] = set()
    for index, item in enumerate(value, start=1):
        where = f"[[channels]][{index}]"
        if not isinstance(item, Mapping):
            ctx.fail(where, f"must be a table, got {_type_name(item)}")
        _reject_unknown(ctx, where, item, _CHANNEL_KEYS)
        name = cast(str, _string(ctx, where, item, "name", required=True, nonempty=True))
        if name in seen:
            ctx.fail(f"{where} name", f"duplicate channel name {name!r}")
        seen.add(name)
        kind = _choice(ctx, where, item, "kind", get_args(ChannelKind), required=True)
        unit = _string(ctx, where, item, "unit") or ""
        channels.append(ChannelConfig(name=name, kind=cast(ChannelKind, kind), unit=unit))
    if not any(c.kind == "accelerometer" for c in channels):
        ctx.fail("[[channels]]", "declare at least one channel of kind 'accelerometer'")
    tach_channels = [c.name for c in channels if c.kind == "tachometer"]
    if len(tach_channels) > 1:
        ctx.fail("[[channels]]", f"more than one tachometer channel: {', '.join(tach_channels)}")
    return tuple(channels)


def _parse_tachometer(
    ctx: _Context, data: Mapping[str, Any], channels: tuple[ChannelConfig, ...]
) -> TachometerConfig | None:
    table = _table(ctx, data, "tachometer", required=False)
    tach_channels = [c.name for c in channels if c.kind == "tachometer"]
    if "tachometer" not in data:
        if tach_channels:
            ctx.fail(
                "[tachometer]",
                f"missing, but [[channels]] declares tachometer channel {tach_channels[0]!r}",
            )
        return None
    _reject_unknown(ctx, "[tachometer]", table, _TACHOMETER_KEYS)
    channel = cast(str, _string(ctx, "[tachometer]", table, "channel", required=True, nonempty=True))
    if channel not in tach_channels:
        declared = {c.name: c.kind for c in channels}
        if channel in declared:
            ctx.fail(
                "[tachometer] channel",
                f"{channel!r} is declared in [[channels]] with kind {declared[channel]!r}, "
                "expected kind 'tachometer'",
            )
        ctx.fail(
            "[tachometer] channel",
            f"{channel!r} is not declared in [[channels]] (add it with kind = 'tachometer')",
        )
    kind = _choice(ctx, "[tachometer]", table, "kind", get_args(TachKind)) or "pulses"
    shaft = _choice(ctx, "[tachometer]", table, "shaft", get_args(Shaft)) or "pinion"
    pulses_per_rev = _positive_int(ctx, "[tachometer]", table, "pulses_per_rev") or 1
    edge = _choice(ctx, "[tachometer]", table, "edge", get_args(TachEdge)) or "rising"
    return TachometerConfig(
        channel=channel,
        kind=cast(TachKind, kind),
        shaft=cast(Shaft, shaft),
        pulses_per_rev=pulses_per_rev,
        edge=cast(TachEdge, edge),
    )


def _parse_records(
    ctx: _Context, value: Any, root: Path, check_files: bool
) -> tuple[RecordEntry, ...]:
    if value is None:
        return ()
    if not isinstance(value, list):
        ctx.fail("records", f"must be an array of tables [[records]], got {_type_name(value)}")
    if len(value) > MAX_RECORDS:
        ctx.fail("[[records]]", f"{len(value)} records, at most {MAX_RECORDS} allowed")
    records: list[RecordEntry] = []
    seen: set[str] = set()
    for index, item in enumerate(value, start=1):
        where = f"[[records]][{index}]"
        if not isinstance(item, Mapping):
            ctx.fail(where, f"must be a table, got {_type_name(item)}")
        _reject_unknown(ctx, where, item, _RECORD_KEYS)
        file = cast(str, _string(ctx, where, item, "file", required=True, nonempty=True))
        if any(len(part) > MAX_FILE_NAME_COMPONENT for part in Path(file).parts):
            ctx.fail(f"{where} file", f"a name in the path is longer than "
                     f"{MAX_FILE_NAME_COMPONENT} characters")
        if file in seen:
            ctx.fail(f"{where} file", f"{file!r} is listed twice")
        seen.add(file)
        if check_files and not (root / file).is_file():
            ctx.fail(f"{where} file", f"record file not found: {root / file}")
        taken_at = _timestamp(ctx, f"{where} taken_at", item.get("taken_at"))
        label = _string(ctx, where, item, "label") or ""
        records.append(RecordEntry(file=file, taken_at=taken_at, label=label))
    return tuple(records)


# --- value checks ---------------------------------------------------------------------


def _reject_unknown(
    ctx: _Context,
    where: str,
    table: Mapping[str, Any],
    allowed: tuple[str, ...],
    *,
    top_level: bool = False,
) -> None:
    unknown = [key for key in table if key not in allowed]
    if unknown:
        names = ", ".join(repr(k) for k in unknown)
        label = "unknown section(s)" if top_level else "unknown key(s)"
        ctx.fail(where, f"{label} {names} (allowed: {', '.join(allowed)})")


def _table(ctx: _Context, data: Mapping[str, Any], key: str, *, required: bool) -> Mapping[str, Any]:
    value = data.get(key)
    if value is None:
        if required:
            ctx.fail(f"[{key}]", "missing section")
        return {}
    if not isinstance(value, Mapping):
        ctx.fail(f"[{key}]", f"must be a table, got {_type_name(value)}")
    return value


def _string(
    ctx: _Context,
    where: str,
    table: Mapping[str, Any],
    key: str,
    *,
    required: bool = False,
    nonempty: bool = False,
) -> str | None:
    value = table.get(key)
    if value is None:
        if required:
            ctx.fail(f"{where} {key}", "missing")
        return None
    if not isinstance(value, str):
        ctx.fail(f"{where} {key}", f"must be a string, got {_type_name(value)} {value!r}")
    if nonempty and not value.strip():
        ctx.fail(f"{where} {key}", "must not be empty")
    longest = MAX_TEXT_LENGTH.get(key)
    if longest is not None and len(value) > longest:
        ctx.fail(f"{where} {key}", f"is {len(value)} characters long, at most {longest} allowed")
    if "\x00" in value:
        ctx.fail(f"{where} {key}", "must not contain a NUL character")
    return value


def _choice(
    ctx: _Context,
    where: str,
    table: Mapping[str, Any],
    key: str,
    choices: tuple[str, ...],
    *,
    required: bool = False,
) -> str | None:
    value = _string(ctx, where, table, key, required=required)
    if value is not None and value not in choices:
        allowed = " | ".join(repr(c) for c in choices)
        ctx.fail(f"{where} {key}", f"must be one of {allowed}, got {value!r}")
    return value


def _positive_int(ctx: _Context, where: str, table: Mapping[str, Any], key: str) -> int | None:
    value = table.get(key)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int):
        ctx.fail(f"{where} {key}", f"must be an integer, got {_type_name(value)} {value!r}")
    if value <= 0:
        ctx.fail(f"{where} {key}", f"must be positive, got {value}")
    low, high = INTEGER_BOUNDS.get(key, (1, 2**31 - 1))
    if not low <= value <= high:
        ctx.fail(f"{where} {key}", f"must be between {low} and {high}, got {value}")
    return value


def _positive_number(
    ctx: _Context, where: str, table: Mapping[str, Any], key: str
) -> float | None:
    value = table.get(key)
    if value is None:
        return None
    if not _is_number(value):
        ctx.fail(f"{where} {key}", f"must be a number, got {_type_name(value)} {value!r}")
    if not (math.isfinite(value) and value > 0):
        ctx.fail(f"{where} {key}", f"must be a positive finite number, got {value!r}")
    low, high = NUMBER_BOUNDS.get(key, (0.0, math.inf))
    if not low <= value <= high:
        ctx.fail(f"{where} {key}", f"must be between {low:g} and {high:g}, got {value!r}")
    return float(value)


def _timestamp(ctx: _Context, where: str, value: Any) -> str:
    if value is None:
        ctx.fail(where, "missing (ISO 8601 with time zone, e.g. \"2026-03-01T09:00:00Z\")")
    if isinstance(value, dt.datetime):
        # An unquoted TOML datetime: keep it, as ISO text.
        parsed = value
        text = value.isoformat()
    elif isinstance(value, str):
        text = value
        try:
            parsed = dt.datetime.fromisoformat(value)
        except ValueError:
            ctx.fail(where, f"not an ISO 8601 timestamp: {value!r}")
    else:
        ctx.fail(where, f"must be an ISO 8601 string, got {_type_name(value)} {value!r}")
    if parsed.tzinfo is None or parsed.utcoffset() is None:
        ctx.fail(where, f"needs a time zone (e.g. 'Z' or '+01:00'): {text!r}")
    return text


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _toml_number(value: float) -> int | float:
    # Write 20000.0 as 20000 so the README example survives a round trip unchanged.
    return int(value) if float(value).is_integer() else float(value)


def _type_name(value: Any) -> str:
    return {
        str: "string",
        int: "integer",
        float: "float",
        bool: "boolean",
        list: "array",
        dict: "table",
    }.get(type(value), type(value).__name__)
