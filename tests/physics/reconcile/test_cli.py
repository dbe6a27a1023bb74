"""``gearwatch reconcile`` as a real process on a simulated campaign (WAV record)."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import pytest
import tomli_w

from physics.campaign import manifest_dict
from physics.config import GearPairModel, Spall, model_from_toml, model_to_toml
from physics.recordio import write_record
from physics.simulator import simulate


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "gearwatch", *args], capture_output=True, text=True, timeout=600
    )


@pytest.fixture(scope="module")
def campaign(tmp_path_factory: pytest.TempPathFactory, base_model: GearPairModel) -> Path:
    root = tmp_path_factory.mktemp("reconcile")
    truth = base_model.replace(
        deviations=dataclasses.replace(base_model.deviations, spalls=[Spall(wheel="pinion", tooth=5, depth_um=6.0)])
    )
    result = simulate(truth, seconds=5.0, seed=9)
    write_record(root / "rec.wav", result.channels, result.sample_rate_hz)
    manifest = manifest_dict(base_model, [{"file": "rec.wav", "taken_at": "2026-03-01T09:00:00Z"}], "c", "test")
    (root / "campaign.toml").write_text(tomli_w.dumps(manifest), encoding="utf-8")
    (root / "model.toml").write_text(model_to_toml(base_model), encoding="utf-8")
    return root


@pytest.mark.slow
def test_reconcile_names_the_spall_and_writes_json_report_and_model(campaign: Path) -> None:
    out = campaign / "out.json"
    proc = run_cli(
        "reconcile", str(campaign / "rec.wav"), "--campaign", str(campaign / "campaign.toml"),
        "--model", str(campaign / "model.toml"), "--json", str(out), "--report", str(campaign / "r.html"),
        "--write-model", str(campaign / "updated.toml"), "--samples-per-mesh", "32",
        "--max-frequency-hz", "4000", "--mechanisms", "tooth_spall,tooth_crack,index_error", "--max-findings", "2",
    )
    assert proc.returncode == 0, proc.stderr
    data = json.loads(out.read_text())
    first = data["findings"][0]
    assert (first["mechanism"], first["wheel"], first["tooth"]) == ("tooth_spall", "pinion", 5), data
    angle = [m for m in data["mismatches"] if m["domain"] == "angle" and m["wheel"] == "pinion"]
    assert angle and angle[0]["teeth"] == [5]
    assert "status" in proc.stdout
    page = (campaign / "r.html").read_text()
    assert page.startswith("<!doctype html>") and '{"' not in page  # tables, no JSON dump
    assert 'id="conclusion"' in page and "tooth spall" in page and "pinion tooth 5" in page
    updated = model_from_toml((campaign / "updated.toml").read_text())
    assert [(s.wheel, s.tooth) for s in updated.deviations.spalls] == [("pinion", 5)]
    # Small band (4 kHz) and two findings at most: depth to 25 %.
    assert updated.deviations.spalls[0].depth_um == pytest.approx(6.0, rel=0.25)


def test_bad_input_is_one_line_not_a_traceback(campaign: Path) -> None:
    proc = run_cli("reconcile", str(campaign / "missing.wav"), "--campaign", str(campaign / "campaign.toml"))
    assert proc.returncode != 0
    assert "Traceback" not in proc.stderr and "missing.wav" in proc.stderr
    proc = run_cli(
        "reconcile", str(campaign / "rec.wav"), "--campaign", str(campaign / "campaign.toml"),
        "--mechanisms", "backlash_gap",
    )
    assert proc.returncode != 0 and "backlash_gap" in proc.stderr and "Traceback" not in proc.stderr
