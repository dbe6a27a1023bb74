"""``gearwatch analyze`` as a user runs it: a real process on real files."""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.io.wavfile
import tomli_w

from dsp.synthetic import synthetic_gear_record

TOOTH1_DEG = 337.4


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "gearwatch", *args], capture_output=True, text=True, timeout=120
    )


def write_manifest(folder: Path, record_file: str, **rig: object) -> Path:
    manifest = {
        "campaign": {"id": "cli-test", "description": "synthetic"},
        "rig": {"id": "rig-1", "pinion_teeth": 20, "gear_teeth": 21,
                "tooth1_pitch_angle_deg": TOOTH1_DEG, **rig},
        "acquisition": {"sample_rate_hz": 20000},
        "tachometer": {"channel": "tach", "kind": "pulses", "shaft": "pinion", "pulses_per_rev": 1},
        "channels": [
            {"name": "acc", "kind": "accelerometer", "unit": "m/s^2"},
            {"name": "tach", "kind": "tachometer", "unit": "V"},
        ],
        "records": [{"file": record_file, "taken_at": "2026-03-01T09:00:00Z", "label": "day 1"}],
    }
    path = folder / "campaign.toml"
    path.write_text(tomli_w.dumps(manifest))
    return path


@pytest.fixture(scope="module")
def campaign_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("campaign")
    synthetic = synthetic_gear_record(
        duration_s=3.0, spall_tooth=16, spall_depth=0.1, tooth1_pitch_angle_deg=TOOTH1_DEG, seed=7
    )
    (folder / "records").mkdir()
    stereo = np.stack([synthetic.acceleration, synthetic.tach_waveform], axis=1).astype(np.float32)
    scipy.io.wavfile.write(folder / "records" / "day01.wav", 20000, stereo)
    np.savez(folder / "records" / "day01.npz", acc=synthetic.acceleration, tach=synthetic.tach_waveform)
    write_manifest(folder, "records/day01.wav")
    return folder


@pytest.mark.parametrize("record", ["records/day01.wav", "records/day01.npz"])
def test_analyze_json_localises_the_spall(campaign_dir: Path, record: str) -> None:
    result = run_cli("analyze", str(campaign_dir / record), "--campaign",
                     str(campaign_dir / "campaign.toml"), "--json")
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["worst_tooth"] == 16
    assert report["samples_per_rev"] == 1280
    assert report["revolutions"] >= 45
    assert abs(report["speed_rpm"] - 1000) < 15
    assert [t["tooth"] for t in report["teeth"]] == list(range(1, 21))
    assert {"mci_depth", "diff_energy", "diff_kurtosis"} <= set(report["teeth"][0])
    assert set(report["metrics"]) == {"rms", "peak", "crest", "kurtosis", "fm0", "fm4", "na4",
                                      "residual_kurtosis", "nb4", "m6a", "m8a", "er", "raw_rms",
                                      "raw_kurtosis"}
    # a single record: NA4's baseline is its own variance, so NA4 is the residual's kurtosis
    assert report["metrics"]["na4"] == pytest.approx(report["metrics"]["residual_kurtosis"])
    assert {"tach_repairs", "speed_variation", "score", "rejected_revolutions",
            "glitch_samples", "dropout_samples", "clipped_samples"} <= set(report["quality"])
    assert 0.0 < report["quality"]["score"] <= 1.0
    assert report["channels"][0]["quality"]["score"] == report["quality"]["score"]
    provenance = report["provenance"]
    import hashlib

    assert provenance["input_sha256"] == hashlib.sha256(
        (campaign_dir / record).read_bytes()).hexdigest()
    assert provenance["code_version"]
    assert provenance["parameters"]["mci_form"] == "robust"


def test_analyze_table_marks_the_worst_tooth(campaign_dir: Path) -> None:
    result = run_cli("analyze", str(campaign_dir / "records/day01.wav"), "--campaign",
                     str(campaign_dir / "campaign.toml"))
    assert result.returncode == 0, result.stderr
    worst_lines = [line for line in result.stdout.splitlines() if "worst" in line and "◀" in line]
    assert len(worst_lines) == 1 and worst_lines[0].split()[0] == "16"


def bad_input_cases(folder: Path) -> dict[str, list[str]]:
    manifest = folder / "campaign.toml"
    (folder / "corrupt.wav").write_bytes(b"RIFF\x00\x00\x00\x00WAVEgarbage")
    truncated = (folder / "records" / "day01.wav").read_bytes()[:200]
    (folder / "truncated.wav").write_bytes(truncated)
    bad_manifest = folder / "bad.toml"
    bad_manifest.write_text(manifest.read_text().replace("[rig]", "[rig]\nspeeed = 3"))
    return {
        "missing record": ["analyze", str(folder / "nope.wav"), "--campaign", str(manifest)],
        "missing manifest": ["analyze", str(folder / "records/day01.wav"), "--campaign",
                             str(folder / "nope.toml")],
        "corrupt wav": ["analyze", str(folder / "corrupt.wav"), "--campaign", str(manifest)],
        "truncated wav": ["analyze", str(folder / "truncated.wav"), "--campaign", str(manifest)],
        "unknown manifest key": ["analyze", str(folder / "records/day01.wav"), "--campaign",
                                 str(bad_manifest)],
        "unknown suffix": ["analyze", str(manifest), "--campaign", str(manifest)],
    }


def test_bad_input_gives_one_clear_line_and_a_nonzero_exit(campaign_dir: Path) -> None:
    for case, args in bad_input_cases(campaign_dir).items():
        result = run_cli(*args)
        assert result.returncode != 0, case
        assert "Traceback" not in result.stderr, (case, result.stderr)
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("gearwatch: error:"), (case, result.stderr)
    unknown = run_cli(*bad_input_cases(campaign_dir)["unknown manifest key"])
    assert "speeed" in unknown.stderr


def blas_threads(environment: dict[str, str], through_cli: bool) -> int:
    """OpenBLAS threads of a fresh process with ``environment`` (``OPENBLAS_NUM_THREADS`` unset
    unless given), numpy imported after ``gearwatch``'s CLI entry point or directly."""
    import os

    cli = "from gearwatch.cli.main import main\ntry:\n    main(['--version'])\nexcept SystemExit:\n    pass\n"
    probe = (cli if through_cli else "") + (
        "import numpy\nfrom threadpoolctl import threadpool_info\n"
        "print(sum(p['num_threads'] for p in threadpool_info() if p['user_api'] == 'blas'))\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"} | environment
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                          timeout=120, env=env, check=True)
    return int(done.stdout.strip().splitlines()[-1])


def test_the_cli_runs_openblas_with_one_thread_unless_told_otherwise() -> None:
    """``gearwatch`` sets ``OPENBLAS_NUM_THREADS`` before numpy is imported (its idle threads
    spun for a fifth of ``analyze``'s CPU); a value the user set wins (whatever OpenBLAS makes of
    it on this machine: the same as without the CLI)."""
    assert blas_threads({}, through_cli=True) == 1
    assert blas_threads({"OPENBLAS_NUM_THREADS": "2"}, through_cli=True) == blas_threads(
        {"OPENBLAS_NUM_THREADS": "2"}, through_cli=False)



KEPT_AFTER_FREE = """
import os, sys, numpy as np
if sys.argv[1] == "keep":
    from gearwatch.cli.main import keep_freed_memory
    assert keep_freed_memory()
def resident() -> int:
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
before = resident()
block = np.ones(2_000_000)  # 16 MB, the size of a block's arrays
del block
print(resident() - before)
"""


@pytest.mark.skipif(
    not sys.platform.startswith("linux") or __import__("platform").libc_ver()[0] != "glibc",
    reason="glibc's mallopt only",
)
def test_a_cli_process_keeps_freed_block_arrays_for_reuse() -> None:
    """``keep_freed_memory`` (called by the CLI's ``main``): a freed 16 MB array stays in the
    process for the next block's arrays, whose pages are then not faulted in and zeroed again;
    with glibc's defaults it is unmapped at once. (Resident memory, not page faults, is what is
    checked: with transparent huge pages a machine faults far fewer pages either way.)"""
    def kept_bytes(mode: str) -> int:
        done = subprocess.run([sys.executable, "-c", KEPT_AFTER_FREE, mode],
                              capture_output=True, text=True, timeout=60, check=True)
        return int(done.stdout)

    assert kept_bytes("keep") >= 12 << 20
    assert kept_bytes("default") < 4 << 20


def _subcommand_options(parser: argparse.ArgumentParser, command: str) -> list[tuple[str, ...]]:
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return [tuple(action.option_strings) or (action.dest,) for action in sub.choices[command]._actions]


def test_a_named_command_gets_the_same_parser_without_importing_the_others() -> None:
    """``gearwatch analyze …`` registers only its own module (start-up time); what it parses is
    what the full parser would parse, and a name that is not a module's falls back to all."""
    from gearwatch.cli.main import build_parser, command_modules, named_command

    full = build_parser()
    sub = next(a for a in full._actions if isinstance(a, argparse._SubParsersAction))
    assert len(sub.choices) == len(command_modules())
    for command in sub.choices:
        assert _subcommand_options(build_parser(command), command) == _subcommand_options(
            full, command), command
    assert named_command(["analyze", "x.wav"]) == "analyze"
    assert named_command(["--version"]) is None and named_command([]) is None
    probe = ("import sys\nfrom gearwatch.cli.main import build_parser\n"
             "parser = build_parser(sys.argv[1])\n"
             "print(sorted(m for m in sys.modules if m.startswith('gearwatch.cli.commands.')))\n")
    imported = {
        name: subprocess.run([sys.executable, "-c", probe, name], capture_output=True, text=True,
                             timeout=120, check=True).stdout.strip()
        for name in ("analyze", "figure-mci", "nosuch")
    }
    assert imported["analyze"] == "['gearwatch.cli.commands.analyze']"
    everything = str(sorted(command_modules()))
    assert imported["figure-mci"] == everything  # registered by the module `figure`
    assert imported["nosuch"] == everything  # argparse then names every valid choice
