"""The ``gearwatch`` command line.

Each sub-command lives in its own module under :mod:`gearwatch.commands` with a
``register(subparsers)`` function that adds its parser and sets ``func`` (a function
taking the parsed arguments and returning the exit code); modules are found automatically. Heavy
imports happen inside the command's function so that ``gearwatch --help`` stays fast.
"""

from __future__ import annotations

import argparse
import importlib
import os
import pkgutil
import sys
from collections.abc import Sequence

from gearwatch.errors import GearwatchError
from gearwatch.version import __version__


def command_modules() -> list[str]:
    """Every module in :mod:`gearwatch.commands` is a sub-command (sorted by name)."""
    import gearwatch.commands as package

    return sorted(f"{package.__name__}.{m.name}" for m in pkgutil.iter_modules(package.__path__))


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="gearwatch",
        description="Condition monitoring for gearbox test rigs: per-tooth MCI and gear metrics.",
    )
    parser.add_argument("--version", action="version", version=f"gearwatch {__version__}")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for module_name in command_modules():
        importlib.import_module(module_name).register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except GearwatchError as error:
        print(f"gearwatch: error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("gearwatch: interrupted", file=sys.stderr)
        return 130
    except Exception as error:  # a bug, not bad input: still one line unless debugging
        if os.environ.get("GEARWATCH_DEBUG"):
            raise
        print(
            f"gearwatch: internal error: {type(error).__name__}: {error} "
            "(set GEARWATCH_DEBUG=1 for a traceback)",
            file=sys.stderr,
        )
        return 70


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
