"""Code version used in provenance records."""

from __future__ import annotations

import functools
import subprocess
from pathlib import Path


@functools.cache
def package_version() -> str:
    """The installed distribution's version (``0.0.0`` in a source tree never installed).

    Read on first use, not at import: ``importlib.metadata`` costs tens of milliseconds that
    ``gearwatch --help`` need not pay.
    """
    from importlib import metadata

    try:
        return metadata.version("gearwatch")
    except metadata.PackageNotFoundError:
        return "0.0.0"


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
