"""Stage progress on stderr (used by ``gearwatch reconcile``)."""

from __future__ import annotations

import pytest

from gearwatch.cli.progress import StageProgress


def test_stages_and_completion_are_shown_on_stderr(capsys: pytest.CaptureFixture[str]) -> None:
    with StageProgress("reconcile day10.wav", ["reading", "fitting", "writing"]) as progress:
        progress.stage("reading")
        progress.stage("fitting")
    err = capsys.readouterr().err
    assert "reconcile day10.wav" in err and "fitting" in err
    assert "3/3 stages" in err and "done" in err


def test_disabled_progress_prints_nothing(capsys: pytest.CaptureFixture[str]) -> None:
    with StageProgress("x", ["a"], enabled=False) as progress:
        progress.stage("a")
    assert capsys.readouterr().err == ""


def test_a_failed_command_does_not_claim_completion(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(RuntimeError), StageProgress("x", ["a", "b"]) as progress:
        progress.stage("a")
        raise RuntimeError("boom")
    assert "done" not in capsys.readouterr().err
