"""The code version stored with every result names the commit, and says when tracked files differ."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from gearwatch.floor import version

ROOT = Path(version.__file__).resolve().parents[2]


def _git(*args: str) -> str:
    return subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, text=True,
                          check=True).stdout.strip()


@pytest.mark.skipif(shutil.which("git") is None or not (ROOT / ".git").exists(),
                    reason="not a git checkout")
def test_the_code_version_is_the_checkouts_commit_and_its_state() -> None:
    version.code_version.cache_clear()
    try:
        found = version.code_version()
    finally:
        version.code_version.cache_clear()
    commit = _git("rev-parse", "--short=12", "HEAD")
    dirty = bool(_git("status", "--porcelain", "--untracked-files=no"))
    assert found == f"{version.VERSION}+g{commit}{'.dirty' if dirty else ''}"


def test_outside_a_checkout_the_package_version_alone(tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PATH", str(tmp_path))  # no git to run
    version.code_version.cache_clear()
    try:
        assert version.code_version() == version.VERSION
    finally:
        version.code_version.cache_clear()
