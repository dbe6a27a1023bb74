"""``gearwatch serve``: run the REST API and dashboard with uvicorn."""

from __future__ import annotations

import argparse
from typing import Any


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "serve",
        help="run the REST API and the dashboard",
        description="Run the REST API and the dashboard (http://HOST:PORT/) with uvicorn. "
        "Settings come from GEARWATCH_* environment variables; --db overrides "
        "GEARWATCH_DATABASE_URL.",
    )
    parser.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1)")
    parser.add_argument("--port", type=int, default=8000, help="port (default 8000)")
    parser.add_argument(
        "--db", metavar="URL", help="database URL (default: sqlite:///gearwatch.db)"
    )
    parser.add_argument("--workers", type=int, default=1, help="uvicorn worker processes")
    parser.add_argument("--log-level", default="info", help="uvicorn log level")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import os

    import uvicorn

    from gearwatch.errors import InputError

    if not 0 < args.port < 65536:
        raise InputError(f"--port {args.port}: not a TCP port")
    if args.workers < 1:
        raise InputError(f"--workers {args.workers}: must be at least 1")
    if args.db:
        # Through the environment, so that every uvicorn worker process sees it too.
        os.environ["GEARWATCH_DATABASE_URL"] = args.db
    uvicorn.run(
        "service.app:create_app",
        factory=True,
        host=args.host,
        port=args.port,
        workers=args.workers,
        log_level=args.log_level,
    )
    return 0
