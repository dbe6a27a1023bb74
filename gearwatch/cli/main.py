"""The ``gearwatch`` command line.

Each sub-command lives in its own module under :mod:`gearwatch.cli.commands` with a
``register(subparsers)`` function that adds its parser and sets ``func`` (a function
taking the parsed arguments and returning the exit code); modules are found automatically. Heavy
imports happen inside the command's function so that ``gearwatch --help`` stays fast.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence

from gearwatch.floor.errors import GearwatchError


class VersionAction(argparse.Action):
    """``--version``: the version is read only when asked for (it costs an ``importlib.metadata``)."""

    def __call__(self, parser: argparse.ArgumentParser, *_: object) -> None:
        from gearwatch.floor.version import package_version

        parser.exit(message=f"gearwatch {package_version()}\n")


def command_modules() -> list[str]:
    """Every module in :mod:`gearwatch.cli.commands` is a sub-command (sorted by name).

    Listed from the folder rather than with ``pkgutil.iter_modules``, which imports ``inspect``
    (a tenth of ``--help``'s imports)."""
    import gearwatch.cli.commands as package

    names = {
        entry.name.removesuffix(".py")
        for folder in package.__path__
        for entry in os.scandir(folder)
        if entry.name.endswith(".py") and not entry.name.startswith("_")
    }
    return [f"{package.__name__}.{name}" for name in sorted(names)]


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The CLI's parser. Given a ``command`` (``analyze``), only the module of that name is
    imported and registered (it skips the other 14: ~15 ms of each run); without one, or when
    no module registers the command under its own name, all of them."""
    parser = argparse.ArgumentParser(
        prog="gearwatch",
        description="Condition monitoring for gearbox test rigs: per-tooth MCI and gear metrics.",
    )
    parser.add_argument("--version", action=VersionAction, nargs=0, help="show the version and exit")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    modules = command_modules()
    wanted = command.replace("-", "_") if command else None
    module_name = next((m for m in modules if m.rsplit(".", 1)[1] == wanted), None)
    if module_name is not None:
        importlib.import_module(module_name).register(subparsers)
        if command in subparsers.choices:
            return parser
        return build_parser(None)
    for module_name in modules:
        importlib.import_module(module_name).register(subparsers)
    return parser


def named_command(argv: Sequence[str] | None) -> str | None:
    """The command a command line (``sys.argv[1:]`` for ``None``) names: its first word, unless
    that is an option."""
    words = sys.argv[1:] if argv is None else list(argv)
    return words[0] if words and not words[0].startswith("-") else None


BLAS_THREADS_DEFAULT = "1"
"""OpenBLAS threads of a ``gearwatch`` process unless ``OPENBLAS_NUM_THREADS`` says otherwise.

gearwatch parallelises over records (worker processes), not inside BLAS: the per-record chain makes
no BLAS call on long arrays, and OpenBLAS's idle threads spin — 0.1 s of the CPU of a 0.55 s
``analyze`` (``benchmarks/bench_chain.py --whole-process``) — and oversubscribe the cores when
several workers run. Set before numpy is first imported (it reads the variable once)."""


MALLOC_MMAP_THRESHOLD_BYTES = 32 << 20
"""Allocations up to this size come from the heap, not from a fresh ``mmap`` (glibc's largest
allowed threshold on 64-bit; its default starts at 128 KiB and only grows as chunks are freed)."""
MALLOC_TRIM_THRESHOLD_BYTES = 256 << 20
"""Freed heap memory a ``gearwatch`` process keeps for reuse before returning it to the system.

The per-record chain allocates and frees arrays of a few MB per block (float64 copies of a block,
the resampled revolutions, their residuals). With glibc's defaults each one is a fresh mapping or
a heap grown and trimmed again, and every page of it is faulted in and zeroed anew: 0.05–0.07 s of
system time of a 0.45 s ``analyze`` of a 300 s record (``benchmarks/bench_chain.py
--whole-process``, 2026-11-28: 0.44 → 0.39 CPU s). A process keeps at most this much unused."""


def keep_freed_memory() -> bool:
    """Tune glibc's allocator as above (``mallopt``); ``False`` where there is no glibc
    (macOS, musl), which then keeps its own defaults."""
    import ctypes

    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (AttributeError, OSError):
        return False
    m_trim_threshold, m_mmap_threshold = -1, -3  # <malloc.h>
    return bool(mallopt(m_mmap_threshold, MALLOC_MMAP_THRESHOLD_BYTES)) and bool(
        mallopt(m_trim_threshold, MALLOC_TRIM_THRESHOLD_BYTES)
    )


def main(argv: Sequence[str] | None = None) -> int:
    os.environ.setdefault("OPENBLAS_NUM_THREADS", BLAS_THREADS_DEFAULT)
    keep_freed_memory()
    from gearwatch.floor.logs import configure_cli_logging

    configure_cli_logging()
    parser = build_parser(named_command(argv))
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except GearwatchError as error:
        print(f"gearwatch: error: {error}", file=sys.stderr)
        return error.exit_code
    except KeyboardInterrupt:
        print("gearwatch: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader went away (`gearwatch … --json | head`): not an error of ours. Point stdout
        # at devnull so the interpreter's final flush cannot raise again (Python docs, SIGPIPE).
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141  # 128 + SIGPIPE, as a shell reports a command killed by a closed pipe
    except Exception as error:  # a bug, not bad input: still one line unless debugging
        unavailable = _unavailable_database(error)
        if unavailable is not None:
            print(f"gearwatch: error: {unavailable}", file=sys.stderr)
            return unavailable.exit_code
        if os.environ.get("GEARWATCH_DEBUG"):
            raise
        print(
            f"gearwatch: internal error: {type(error).__name__}: {error} "
            "(set GEARWATCH_DEBUG=1 for a traceback)",
            file=sys.stderr,
        )
        return 70


def _unavailable_database(error: Exception) -> GearwatchError | None:
    """A database that cannot be reached (or went away mid-command) as one clear line, not an
    SQL dump. Every command commits per record, so running it again resumes."""
    if not type(error).__module__.startswith("sqlalchemy"):
        return None
    from storage.db import database_unavailable

    return database_unavailable(error)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
