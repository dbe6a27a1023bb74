"""Campaign manifest: the README example, strict errors naming the key or file, dump/load round trip."""

from __future__ import annotations

import doctest
import tomllib
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gearwatch.floor.campaign import (
    Campaign,
    ChannelConfig,
    RecordEntry,
    RigConfig,
    TachometerConfig,
)
from gearwatch.floor.errors import ManifestError, RecordRejected
from ingest.manifest import dump_manifest, load_manifest, parse_manifest, require_tachometer
from ingest.sources import read_record
from tests.conftest import IN_CI

REPO = Path(__file__).resolve().parents[2]

README_EXAMPLE = """\
[campaign]
id = "cetim-c10"                 # unique
description = "spur pair fatigue test"

[rig]
id = "rig-1"
pinion_teeth = 20                # optional: without teeth, per-tooth results are omitted, the rest kept
gear_teeth = 21
tooth1_pitch_angle_deg = 337.4   # pinion angle after the tach reference edge at which pinion tooth 1 passes the pitch point

[acquisition]
sample_rate_hz = 20000           # used when the file does not carry its own

[tachometer]
channel = "tach"
kind = "pulses"                  # "pulses" (a waveform) | "pulse_times" (seconds)
shaft = "pinion"                 # "pinion" | "gear"
pulses_per_rev = 1

[[channels]]
name = "acc"
kind = "accelerometer"
unit = "m/s^2"

[[channels]]
name = "tach"
kind = "tachometer"
unit = "V"

[[records]]
file = "records/day01.wav"
taken_at = "2026-03-01T09:00:00Z"
label = "day 1"
"""


def example_data() -> dict[str, Any]:
    return tomllib.loads(README_EXAMPLE)


def parse(data: dict[str, Any], root: Path = Path("/nowhere")) -> Campaign:
    return parse_manifest(data, root=root, source="campaign.toml", check_files=False)


@pytest.fixture
def campaign_dir(tmp_path: Path) -> Path:
    (tmp_path / "records").mkdir()
    (tmp_path / "records" / "day01.wav").write_bytes(b"RIFF")
    (tmp_path / "campaign.toml").write_text(README_EXAMPLE, encoding="utf-8")
    return tmp_path


def test_readme_example_parses_to_the_documented_values(campaign_dir: Path) -> None:
    campaign = load_manifest(campaign_dir / "campaign.toml")
    assert campaign == Campaign(
        id="cetim-c10",
        description="spur pair fatigue test",
        rig=RigConfig(id="rig-1", pinion_teeth=20, gear_teeth=21, tooth1_pitch_angle_deg=337.4),
        sample_rate_hz=20000.0,
        tachometer=TachometerConfig(channel="tach", kind="pulses", shaft="pinion", pulses_per_rev=1),
        channels=(
            ChannelConfig(name="acc", kind="accelerometer", unit="m/s^2"),
            ChannelConfig(name="tach", kind="tachometer", unit="V"),
        ),
        records=(RecordEntry(file="records/day01.wav", taken_at="2026-03-01T09:00:00Z", label="day 1"),),
        root=campaign_dir.resolve(),
    )
    assert campaign.record_path(campaign.records[0]) == campaign_dir.resolve() / "records/day01.wav"
    assert [c.name for c in campaign.accelerometer_channels] == ["acc"]


def test_dump_then_load_gives_the_same_campaign(campaign_dir: Path) -> None:
    campaign = load_manifest(campaign_dir / "campaign.toml")
    (campaign_dir / "again.toml").write_text(dump_manifest(campaign), encoding="utf-8")
    assert load_manifest(campaign_dir / "again.toml") == campaign


def test_defaults_of_optional_keys() -> None:
    data = example_data()
    del data["rig"]["pinion_teeth"], data["rig"]["gear_teeth"], data["rig"]["tooth1_pitch_angle_deg"]
    del data["acquisition"], data["records"], data["campaign"]["description"]
    data["tachometer"] = {"channel": "tach"}
    data["channels"][0] = {"name": "acc", "kind": "accelerometer"}
    campaign = parse(data)
    assert campaign.rig == RigConfig(id="rig-1")
    assert campaign.sample_rate_hz is None and campaign.records == () and campaign.description == ""
    assert campaign.tachometer == TachometerConfig(channel="tach")
    assert campaign.channels[0].unit == ""
    assert parse(tomllib.loads(dump_manifest(campaign))) == campaign


def test_unquoted_toml_datetime_is_accepted_as_iso_text() -> None:
    data = tomllib.loads(README_EXAMPLE.replace('"2026-03-01T09:00:00Z"', "2026-03-01T09:00:00Z"))
    assert parse(data).records[0].taken_at == "2026-03-01T09:00:00+00:00"


def test_several_accelerometers_are_kept_in_order() -> None:
    data = example_data()
    data["channels"].insert(1, {"name": "acc_axial", "kind": "accelerometer"})
    assert [c.name for c in parse(data).accelerometer_channels] == ["acc", "acc_axial"]


# --- errors -------------------------------------------------------------------------------


def set_key(data: dict[str, Any], dotted: str, value: Any) -> None:
    *parents, last = dotted.split(".")
    node: Any = data
    for part in parents:
        node = node[int(part)] if part.isdigit() else node[part]
    node[last] = value


@pytest.mark.parametrize(
    ("dotted", "named"),
    [
        ("extra", "'extra'"),
        ("campaign.owner", "[campaign]: unknown key(s) 'owner'"),
        ("rig.teeth", "[rig]: unknown key(s) 'teeth'"),
        ("acquisition.rate", "[acquisition]: unknown key(s) 'rate'"),
        ("tachometer.ppr", "[tachometer]: unknown key(s) 'ppr'"),
        ("channels.1.gain", "[[channels]][2]: unknown key(s) 'gain'"),
        ("records.0.comment", "[[records]][1]: unknown key(s) 'comment'"),
    ],
)
def test_unknown_keys_are_named(dotted: str, named: str) -> None:
    data = example_data()
    set_key(data, dotted, 1)
    with pytest.raises(ManifestError) as error:
        parse(data)
    assert named in str(error.value)
    assert str(error.value).startswith("campaign.toml: ")


@pytest.mark.parametrize(
    ("dotted", "value", "named"),
    [
        ("campaign.id", 7, r"\[campaign\] id: must be a string, got integer 7"),
        ("campaign.id", " ", r"\[campaign\] id: must not be empty"),
        ("rig.pinion_teeth", "20", r"\[rig\] pinion_teeth: must be an integer, got string '20'"),
        ("rig.pinion_teeth", 20.0, r"\[rig\] pinion_teeth: must be an integer"),
        ("rig.pinion_teeth", True, r"\[rig\] pinion_teeth: must be an integer, got boolean"),
        ("rig.gear_teeth", 0, r"\[rig\] gear_teeth: must be positive"),
        ("rig.tooth1_pitch_angle_deg", "337.4", r"tooth1_pitch_angle_deg: must be a finite number"),
        ("rig.tooth1_pitch_angle_deg", 360.0, r"tooth1_pitch_angle_deg: must be in \[0, 360\)"),
        ("acquisition.sample_rate_hz", "20000", r"\[acquisition\] sample_rate_hz: must be a number"),
        ("acquisition.sample_rate_hz", -1, r"sample_rate_hz: must be a positive finite number"),
        ("acquisition.sample_rate_hz", float("inf"), r"sample_rate_hz: must be a positive finite"),
        ("tachometer.kind", "edges", r"\[tachometer\] kind: must be one of 'pulses' \| 'pulse_times'"),
        ("tachometer.shaft", "output", r"\[tachometer\] shaft: must be one of 'pinion' \| 'gear'"),
        ("tachometer.pulses_per_rev", 0, r"\[tachometer\] pulses_per_rev: must be positive"),
        ("tachometer.edge", "up", r"\[tachometer\] edge: must be one of 'rising' \| 'falling'"),
        ("tachometer.channel", "acc", r"'acc' is declared in \[\[channels\]\] with kind 'accelerometer'"),
        ("tachometer.channel", "speed", r"'speed' is not declared in \[\[channels\]\]"),
        ("channels.0.kind", "microphone", r"\[\[channels\]\]\[1\] kind: must be one of"),
        ("channels.1.name", "acc", r"\[\[channels\]\]\[2\] name: duplicate channel name 'acc'"),
        ("channels.0.unit", 3, r"\[\[channels\]\]\[1\] unit: must be a string"),
        ("channels", {"name": "acc"}, r"channels: must be an array of tables"),
        ("rig", "rig-1", r"\[rig\]: must be a table, got string"),
        ("records.0.taken_at", "2026-03-01T09:00:00", r"taken_at: needs a time zone"),
        ("records.0.taken_at", "yesterday", r"\[\[records\]\]\[1\] taken_at: not an ISO 8601"),
        ("records.0.taken_at", 20260301, r"taken_at: must be an ISO 8601 string, got integer"),
        ("records.0.file", "", r"\[\[records\]\]\[1\] file: must not be empty"),
    ],
)
def test_wrong_values_are_named(dotted: str, value: Any, named: str) -> None:
    data = example_data()
    set_key(data, dotted, value)
    with pytest.raises(ManifestError, match=named):
        parse(data)


@pytest.mark.parametrize(
    ("section", "key", "named"),
    [
        ("campaign", None, r"\[campaign\]: missing section"),
        ("rig", None, r"\[rig\]: missing section"),
        ("channels", None, r"\[\[channels\]\]: missing"),
        ("campaign", "id", r"\[campaign\] id: missing"),
        ("rig", "id", r"\[rig\] id: missing"),
        ("tachometer", "channel", r"\[tachometer\] channel: missing"),
        ("channels", "name", r"\[\[channels\]\]\[1\] name: missing"),
        ("channels", "kind", r"\[\[channels\]\]\[1\] kind: missing"),
        ("records", "file", r"\[\[records\]\]\[1\] file: missing"),
        ("records", "taken_at", r"\[\[records\]\]\[1\] taken_at: missing"),
    ],
)
def test_missing_required_keys_are_named(section: str, key: str | None, named: str) -> None:
    data = example_data()
    if key is None:
        del data[section]
    elif isinstance(data[section], list):
        del data[section][0][key]
    else:
        del data[section][key]
    with pytest.raises(ManifestError, match=named):
        parse(data)


def test_channel_set_rules() -> None:
    data = example_data()
    data["channels"] = [{"name": "tach", "kind": "tachometer"}]
    with pytest.raises(ManifestError, match="at least one channel of kind 'accelerometer'"):
        parse(data)
    data = example_data()
    data["channels"].append({"name": "tach2", "kind": "tachometer"})
    with pytest.raises(ManifestError, match="more than one tachometer channel: tach, tach2"):
        parse(data)


def test_tooth_counts_go_together() -> None:
    data = example_data()
    del data["rig"]["gear_teeth"]
    with pytest.raises(ManifestError, match=r"\[rig\]: pinion_teeth and gear_teeth go together"):
        parse(data)


def test_duplicate_record_file_is_named() -> None:
    data = example_data()
    data["records"].append(dict(data["records"][0]))
    with pytest.raises(ManifestError, match=r"\[\[records\]\]\[2\] file: 'records/day01.wav' is listed twice"):
        parse(data)


def test_missing_record_file_is_named(tmp_path: Path) -> None:
    manifest = tmp_path / "campaign.toml"
    manifest.write_text(README_EXAMPLE, encoding="utf-8")
    with pytest.raises(ManifestError) as error:
        load_manifest(manifest)
    message = str(error.value)
    assert message.startswith(str(manifest)) and "[[records]][1] file" in message
    assert "record file not found" in message and "day01.wav" in message
    assert load_manifest(manifest, check_files=False).records[0].file == "records/day01.wav"


def test_unreadable_manifests_are_named(tmp_path: Path) -> None:
    with pytest.raises(ManifestError, match=r"absent\.toml: manifest file not found"):
        load_manifest(tmp_path / "absent.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[campaign\nid = 1", encoding="utf-8")
    with pytest.raises(ManifestError, match=r"bad\.toml: not valid TOML"):
        load_manifest(bad)
    binary = tmp_path / "binary.toml"
    binary.write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(ManifestError, match=r"binary\.toml"):
        load_manifest(binary)


# --- no tachometer ------------------------------------------------------------------------


def test_tachometer_may_be_omitted_and_records_are_then_rejected_by_require_tachometer() -> None:
    data = example_data()
    del data["tachometer"]
    data["channels"].pop()  # the tach channel
    campaign = parse(data)
    assert campaign.tachometer is None
    assert "tachometer" not in tomllib.loads(dump_manifest(campaign))
    assert parse(tomllib.loads(dump_manifest(campaign))) == campaign
    with pytest.raises(RecordRejected, match=r"no \[tachometer\].*impossible"):
        require_tachometer(campaign)
    assert require_tachometer(parse(example_data())).channel == "tach"


def test_tachometer_channel_without_tachometer_section_is_an_error() -> None:
    data = example_data()
    del data["tachometer"]
    with pytest.raises(ManifestError, match=r"\[tachometer\]: missing, but \[\[channels\]\] declares"):
        parse(data)


# --- property: dump/parse round trip --------------------------------------------------------

names = st.text(
    alphabet=st.characters(codec="utf-8", exclude_categories=("Cs", "Cc")), min_size=1, max_size=12
).filter(lambda s: s.strip() != "")


@st.composite
def campaigns(draw: st.DrawFn) -> Campaign:
    accelerometers = draw(st.lists(names, min_size=1, max_size=4, unique=True))
    tach_name = draw(names.filter(lambda n: n not in accelerometers))
    with_tach = draw(st.booleans())
    channels = [
        ChannelConfig(name=n, kind="accelerometer", unit=draw(st.sampled_from(["", "g", "m/s^2"])))
        for n in accelerometers
    ]
    tachometer = None
    if with_tach:
        channels.insert(draw(st.integers(0, len(channels))), ChannelConfig(tach_name, "tachometer", "V"))
        tachometer = TachometerConfig(
            channel=tach_name,
            kind=draw(st.sampled_from(["pulses", "pulse_times"])),
            shaft=draw(st.sampled_from(["pinion", "gear"])),
            pulses_per_rev=draw(st.integers(1, 360)),
            edge=draw(st.sampled_from(["rising", "falling"])),
        )
    teeth = draw(st.one_of(st.none(), st.tuples(st.integers(3, 500), st.integers(3, 500))))
    files = draw(st.lists(names, max_size=3, unique=True))
    records = tuple(
        RecordEntry(
            file=f"records/{f}.wav",
            taken_at=draw(st.sampled_from(["2026-03-01T09:00:00Z", "2026-03-02T10:30:00+01:00"])),
            label=draw(st.text(st.characters(blacklist_characters='\x00'), max_size=10)),
        )
        for f in files
    )
    return Campaign(
        id=draw(names),
        description=draw(st.text(st.characters(blacklist_characters='\x00'), max_size=30)),
        rig=RigConfig(
            id=draw(names),
            pinion_teeth=teeth[0] if teeth else None,
            gear_teeth=teeth[1] if teeth else None,
            tooth1_pitch_angle_deg=draw(st.floats(0.0, 360.0, exclude_max=True)),
        ),
        sample_rate_hz=draw(st.one_of(st.none(), st.floats(1.0, 1e7))),
        tachometer=tachometer,
        channels=tuple(channels),
        records=records,
        root=Path("/campaigns/x"),
    )


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(campaigns())
def test_parse_of_dump_is_identity(campaign: Campaign) -> None:
    text = dump_manifest(campaign)
    assert parse(tomllib.loads(text), root=campaign.root) == campaign


# --- the example campaigns on real data -------------------------------------------------------


@pytest.mark.parametrize("name", ["windturbine-hss", "spectraquest-gfd"])
def test_example_manifests_load_and_their_records_read(name: str) -> None:
    manifest = REPO / "examples" / name / "campaign.toml"
    shared = REPO.parent / "shared" / "data" / "real" / name
    if not shared.is_dir():
        if IN_CI:
            pytest.fail(f"{shared} is missing: CI must clone the repository with shared/ beside it")
        pytest.skip(f"{shared} not present")
    campaign = load_manifest(manifest)
    assert len(campaign.records) in (10, 20)
    record = read_record(campaign.record_path(campaign.records[0]), campaign)
    assert set(record.channels) == {c.name for c in campaign.channels}
    if name == "spectraquest-gfd":
        assert campaign.tachometer is None  # the angle comes from the mesh phase (issue 11)
        assert (campaign.rig.pinion_teeth, campaign.rig.gear_teeth) == (32, 80)
        with pytest.raises(RecordRejected):
            require_tachometer(campaign)
    else:
        assert campaign.tachometer is not None and campaign.tachometer.kind == "pulse_times"
        assert record.sample_rate_hz == 97_656.0


def test_docstring_examples_run() -> None:
    import ingest.manifest
    import ingest.sources

    for module in (ingest.manifest, ingest.sources):
        result = doctest.testmod(module)
        assert result.attempted > 0 and result.failed == 0, module.__name__
