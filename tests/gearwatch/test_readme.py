"""README's set-up commands are the ones CI runs."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def setup_commands() -> list[str]:
    readme = (ROOT / "README.md").read_text()
    section = readme.split("## Set-up: two commands", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```bash\n(.+?)\n\s*```", section, flags=re.S)


def test_readme_has_exactly_two_setup_commands_each_creating_a_venv() -> None:
    commands = [c.strip() for c in setup_commands()]
    assert len(commands) == 2, commands
    for command in commands:
        assert command.startswith("python3 -m venv .venv && ")
        assert "\n" not in command


def test_ci_runs_the_readme_test_command_verbatim() -> None:
    test_command = setup_commands()[1].strip()
    ci_lines = [line.strip() for line in (ROOT / ".ci" / "run").read_text().splitlines()]
    assert test_command in ci_lines
