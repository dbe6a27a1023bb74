"""Issue 12 item 4: every number and text of a manifest is bounded, each violation one
:class:`ManifestError` naming the key (never a hang, a MemoryError or a ValueError deep in
the chain)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from gearwatch.floor.errors import ManifestError
from tests.ingest.test_manifest import example_data, parse, set_key


@pytest.mark.parametrize(
    ("dotted", "value", "named"),
    [
        ("rig.pinion_teeth", 100_000, r"\[rig\] pinion_teeth: must be between 3 and 500, got 100000"),
        ("rig.pinion_teeth", 10**7, r"\[rig\] pinion_teeth: must be between 3 and 500"),
        ("rig.pinion_teeth", 1, r"\[rig\] pinion_teeth: must be between 3 and 500, got 1"),
        ("rig.gear_teeth", 2, r"\[rig\] gear_teeth: must be between 3 and 500, got 2"),
        ("rig.gear_teeth", 2**63 - 1, r"\[rig\] gear_teeth: must be between 3 and 500"),
        ("tachometer.pulses_per_rev", 10**9, r"\[tachometer\] pulses_per_rev: must be between 1 "),
        ("acquisition.sample_rate_hz", 1e300, r"\[acquisition\] sample_rate_hz: must be between"),
        ("acquisition.sample_rate_hz", 1e-3, r"\[acquisition\] sample_rate_hz: must be between"),
        ("records.0.file", "x" * 5000, r"\[\[records\]\]\[1\] file: is 5000 characters long"),
        ("records.0.file", "d/" + "x" * 300, r"\[\[records\]\]\[1\] file: a name in the path is"),
        ("records.0.file", "a\x00b", r"\[\[records\]\]\[1\] file: must not contain a NUL"),
        ("records.0.label", "l" * 201, r"\[\[records\]\]\[1\] label: is 201 characters long"),
        ("campaign.id", "c" * 201, r"\[campaign\] id: is 201 characters long, at most 200"),
        ("rig.id", "r" * 1000, r"\[rig\] id: is 1000 characters long"),
        ("channels.0.name", "n" * 201, r"\[\[channels\]\]\[1\] name: is 201 characters long"),
        ("channels.0.unit", "u" * 33, r"\[\[channels\]\]\[1\] unit: is 33 characters long"),
        ("campaign.description", "d" * 10_001, r"\[campaign\] description: is 10001 characters"),
    ],
)
def test_out_of_bounds_values_are_named(dotted: str, value: Any, named: str) -> None:
    data = example_data()
    set_key(data, dotted, value)
    with pytest.raises(ManifestError, match=named):
        parse(data)


def test_too_many_channels_or_records_are_refused() -> None:
    data = example_data()
    data["channels"] = [*data["channels"], *(
        {"name": f"a{i}", "kind": "accelerometer"} for i in range(64))]
    with pytest.raises(ManifestError, match=r"\[\[channels\]\]: 66 channels, at most 64"):
        parse(data)
    data = example_data()
    data["records"] = [{"file": f"r{i}.wav", "taken_at": "2026-03-01T09:00:00Z"}
                       for i in range(100_001)]
    with pytest.raises(ManifestError, match=r"\[\[records\]\]: 100001 records, at most 100000"):
        parse(data)


def test_bounds_keep_real_rigs() -> None:
    data = example_data()
    for dotted, value in [("rig.pinion_teeth", 3), ("rig.gear_teeth", 500),
                          ("tachometer.pulses_per_rev", 4096),
                          ("acquisition.sample_rate_hz", 97656.25)]:
        set_key(data, dotted, value)
    campaign = parse(data)
    assert (campaign.rig.pinion_teeth, campaign.rig.gear_teeth) == (3, 500)


def test_the_cli_names_the_key_for_a_huge_tooth_count(tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    from gearwatch.cli.main import main
    from tests.gearwatch.jobfixtures import make_campaign

    make_campaign(tmp_path / "camp", [1.0])
    manifest = tmp_path / "camp" / "campaign.toml"
    manifest.write_text(manifest.read_text().replace("pinion_teeth = 20", "pinion_teeth = 100000"))
    code = main(["analyze", str(tmp_path / "camp" / "day00.wav"), "--campaign", str(manifest)])
    err = capsys.readouterr().err
    assert code == 2 and "[rig] pinion_teeth: must be between 3 and 500" in err
    assert len(err.splitlines()) == 1
