"""``gearwatch simulate`` and ``gearwatch simulate-campaign`` from the command line."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest

from gearwatch.cli.main import main
from physics.config import GearPairModel, model_from_toml


def test_simulate_writes_hdf5_with_rate_and_channels(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "rec.h5"
    assert main(["simulate", str(out), "--seconds", "0.2", "--seed", "2"]) == 0
    with h5py.File(out) as f:
        assert f.attrs["sample_rate_hz"] == 20000.0
        assert sorted(f) == ["acc", "tach"]
        assert f["acc"].shape == (4000,) and f["acc"].dtype == np.float64
    assert "tooth1_pitch_angle_deg = 337.4" in capsys.readouterr().out


def test_print_model_round_trips_and_is_accepted(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["simulate", "--print-model"]) == 0
    text = capsys.readouterr().out
    assert model_from_toml(text) == GearPairModel()
    model_file = tmp_path / "m.toml"
    model_file.write_text(text.replace("speed_rpm = 1000.0", "speed_rpm = 1500.0"))
    assert (
        main(["simulate", str(tmp_path / "r.wav"), "--model", str(model_file), "--seconds", "0.1"])
        == 0
    )


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["simulate", "{tmp}/r.wav", "--model", "{tmp}/missing.toml"], "no such model file"),
        (["simulate", "{tmp}/r.wav", "--model", "{tmp}/bad.toml"], "geometry.modul_mm"),
        (["simulate", "{tmp}/r.mp3", "--seconds", "0.1"], "unknown record format"),
        (["simulate", "{tmp}/r.wav", "--seconds", "0"], "--seconds"),
        (["simulate", "{tmp}/r.wav", "--seconds", "0.00001"], "two output samples"),
        (["simulate"], "OUT_FILE is required"),
        (["simulate-campaign", "{tmp}/c", "--spall-tooth", "25"], "--spall-tooth"),
        (["simulate-campaign", "{tmp}/c", "--days", "0"], "--days"),
        (["simulate-campaign", "{tmp}/c", "--start", "yesterday"], "--start"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], message: str
) -> None:
    (tmp_path / "bad.toml").write_text("[geometry]\nmodul_mm = 3\n")
    code = main([a.format(tmp=tmp_path) for a in argv])
    err = capsys.readouterr().err
    assert code == 2
    assert message in err and len(err.strip().splitlines()) == 1


def test_simulate_campaign_refuses_a_non_empty_directory(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "keep.txt").write_text("x")
    assert main(["simulate-campaign", str(tmp_path), "--days", "1", "--seconds", "0.1"]) == 2
    assert "not empty" in capsys.readouterr().err
    argv = ["simulate-campaign", str(tmp_path), "--days", "2", "--seconds", "0.2", "--force",
            "--format", "tdms", "--onset-day", "2", "--campaign-id", "t1"]  # fmt: skip
    assert main(argv) == 0
    assert (tmp_path / "records" / "day02.tdms").is_file()
    assert 'id = "t1"' in (tmp_path / "campaign.toml").read_text()


@pytest.mark.slow
def test_figure_mci_writes_a_png(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "fig6.png"
    assert main(["figure-mci", str(out), "--seconds", "2"]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert out.stat().st_size > 50_000
    assert main(["figure-mci", str(tmp_path / "fig.pdf")]) == 2
    assert "PNG" in capsys.readouterr().err
