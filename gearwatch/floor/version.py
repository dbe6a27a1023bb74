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
        # one process (~5 ms) for the commit and whether tracked files differ from it; every tag
        # excluded, so the answer is the abbreviated commit whatever tags the checkout has
        described = subprocess.run(
            ["git", "-C", str(root), "describe", "--always", "--abbrev=12", "--dirty=.dirty",
             "--exclude=*"],
            capture_output=True, text=True, timeout=5, check=True,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return package_version()
    if not described:
        return package_version()
    return f"{package_version()}+g{described}"
