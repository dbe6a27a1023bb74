"""Code version used in provenance records."""

from __future__ import annotations

import functools
import subprocess
from pathlib import Path

VERSION = "0.1.0"
"""The package's version, defined here once: ``pyproject.toml`` reads it
(``[tool.setuptools.dynamic]``), so no ``importlib.metadata`` lookup (~20 ms) is paid at run time."""


def package_version() -> str:
    """The package's version (:data:`VERSION`)."""
    return VERSION


def __getattr__(name: str) -> str:
    """``__version__``, computed on first access (PEP 562)."""
    if name == "__version__":
        return package_version()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


@functools.cache
def code_version() -> str:
    """Return ``<package version>`` plus ``+g<commit>`` (and ``.dirty``) when run from a git checkout.

    Stored with every result so that a value can say which code produced it.
    """
    root = Path(__file__).resolve().parent.parent
    try:
        sha = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "--short=12", "HEAD"],
            capture_output=True, text=True, timeout=5, check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True, text=True, timeout=5, check=True,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return package_version()
    if not sha:
        return package_version()
    return f"{package_version()}+g{sha}{'.dirty' if dirty else ''}"
