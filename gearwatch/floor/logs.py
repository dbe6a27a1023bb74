"""Logging of the command line: gearwatch's own messages and the libraries' (nptdms, h5py,
python-can, numpy's floating-point warnings through :mod:`warnings`) go through one handler,
one line per message, so that a failing command still ends with exactly one error line.

Library records reach stderr only at ERROR by default (nptdms installs a handler of its own that printed
every truncated-segment warning; numpy printed overflow warnings; a reader once dumped 100 kB of
raw bytes): ``GEARWATCH_LOG_LEVEL=INFO`` or ``DEBUG`` (or ``GEARWATCH_DEBUG=1``) shows them,
tracebacks included.
"""

from __future__ import annotations

import logging
import os
import sys

LIBRARY_LOGGERS = ("nptdms", "h5py", "can", "cantools", "py.warnings", "numba", "matplotlib",
                   "asyncio", "psycopg")
"""psycopg warns "error ignored terminating <Pipeline [BAD]>: the connection is lost" when the
database goes away mid-command, before gearwatch's own one-line "database unavailable" error
(seen once in CI, 2026-11-28: ``tests/gearwatch/test_faults.py``)."""
MAX_LINE_CHARS = 500
_library_level: int | None = None
"""Below it, library records are dropped by :class:`OneLineHandler` (``None``: not configured)."""


class OneLineHandler(logging.StreamHandler):
    """Every record as one line of at most :data:`MAX_LINE_CHARS` characters (tracebacks
    only when debugging)."""

    def __init__(self, *, tracebacks: bool) -> None:
        super().__init__(sys.stderr)
        self.tracebacks = tracebacks
        self.setFormatter(logging.Formatter("gearwatch: %(levelname)s: %(name)s: %(message)s"))
        self.addFilter(_quiet_libraries)

    def emit(self, record: logging.LogRecord) -> None:
        self.stream = sys.stderr  # whatever stderr is now (tests and tools swap it)
        super().emit(record)

    def format(self, record: logging.LogRecord) -> str:
        if self.tracebacks:
            return super().format(record)
        saved = record.exc_info, record.exc_text, record.stack_info
        record.exc_info = record.exc_text = record.stack_info = None
        try:
            text = super().format(record)
        finally:
            record.exc_info, record.exc_text, record.stack_info = saved
        text = " ".join(text.split())
        if len(text) > MAX_LINE_CHARS:
            text = text[: MAX_LINE_CHARS - 1] + "…"
        return text


def _is_library(name: str) -> bool:
    return any(name == lib or name.startswith(lib + ".") for lib in LIBRARY_LOGGERS)


def _quiet_libraries(record: logging.LogRecord) -> bool:
    """Library records below the library level are dropped here, at the handler, not at their
    loggers: gearwatch's readers still see them (the TDMS reader learns of a truncated file
    from nptdms's warnings)."""
    if _library_level is None or not _is_library(record.name):
        return True
    return record.levelno >= _library_level


def configure_cli_logging() -> None:
    """Install the one-line handler on the root logger (once) and quiet the libraries."""
    debug = bool(os.environ.get("GEARWATCH_DEBUG"))
    named = os.environ.get("GEARWATCH_LOG_LEVEL", "").strip().upper()
    level = logging.getLevelName(named) if named else (logging.DEBUG if debug else None)
    if not isinstance(level, int):
        level = None
    logging.captureWarnings(True)
    root = logging.getLogger()
    if not any(isinstance(h, OneLineHandler) for h in root.handlers):
        root.addHandler(OneLineHandler(tracebacks=debug))
    root.setLevel(level if level is not None else logging.WARNING)
    global _library_level
    _library_level = level if level is not None else logging.ERROR
    adopt_library_loggers()


def adopt_library_loggers() -> None:
    """Route every library logger that exists now (and its children) through the root logger:
    their own handlers removed (nptdms attaches one to each of its modules' loggers at import,
    so its reader calls this after importing it), at the configured level."""
    for name in list(logging.root.manager.loggerDict):
        if not _is_library(name):
            continue
        library = logging.getLogger(name)
        for handler in list(library.handlers):
            if isinstance(handler, logging.StreamHandler):  # the library's own printer
                library.removeHandler(handler)
        library.propagate = True
