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
    from gearwatch.cli.shared import serve_api

    serve_api(args.host, args.port, database_url=args.db, workers=args.workers,
              log_level=args.log_level)
    return 0
