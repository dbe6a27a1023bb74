"""``gearwatch keys``: create, list and revoke API keys."""

from __future__ import annotations

import argparse
from typing import Any

ROLES = ("viewer", "operator", "admin")


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "keys",
        help="manage API keys",
        description="Manage the service's API keys (stored hashed; a key is shown once).",
    )
    actions = parser.add_subparsers(dest="keys_action", required=True, metavar="ACTION")

    create = actions.add_parser(
        "create", help="create a key and print it alone on stdout", description="Create a key."
    )
    create.add_argument("--role", required=True, choices=ROLES, help="what the key may do")
    create.add_argument("--name", default="", help="who or what uses the key")
    create.add_argument("--db", metavar="URL", help="database URL (default: settings)")
    create.set_defaults(func=create_key)

    listing = actions.add_parser("list", help="list keys (never the keys themselves)")
    listing.add_argument("--db", metavar="URL", help="database URL (default: settings)")
    listing.set_defaults(func=list_keys)

    revoke = actions.add_parser("revoke", help="revoke a key by its prefix")
    revoke.add_argument("prefix", help="the key's prefix (second field of gw_<prefix>_<secret>)")
    revoke.add_argument("--db", metavar="URL", help="database URL (default: settings)")
    revoke.set_defaults(func=revoke_key)


def _database_url(args: argparse.Namespace) -> str:
    if args.db:
        return str(args.db)
    from gearwatch.floor.settings import Settings

    return Settings().database_url


def create_key(args: argparse.Namespace) -> int:
    from gearwatch.usecases.keys import create_api_key

    print(create_api_key(_database_url(args), role=args.role, name=args.name))
    return 0


def list_keys(args: argparse.Namespace) -> int:
    from storage.db import open_database, session_scope
    from storage.repositories import ApiKeyRepository

    engine, factory = open_database(_database_url(args))
    try:
        with session_scope(factory) as session:
            keys = ApiKeyRepository(session).list()
            print(f"{'prefix':<12} {'role':<9} {'created':<20} {'status':<8} name")
            for key in keys:
                status = "revoked" if key.revoked_at else "active"
                created = key.created_at.strftime("%Y-%m-%d %H:%M")
                print(f"{key.prefix:<12} {key.role:<9} {created:<20} {status:<8} {key.name}")
    finally:
        engine.dispose()
    return 0


def revoke_key(args: argparse.Namespace) -> int:
    from gearwatch.floor.errors import NotFound
    from storage.db import open_database, session_scope
    from storage.repositories import ApiKeyRepository, AuditRepository

    engine, factory = open_database(_database_url(args))
    try:
        with session_scope(factory) as session:
            keys = ApiKeyRepository(session)
            match = [k for k in keys.list() if k.prefix == args.prefix]
            if not match:
                raise NotFound(f"no active key with prefix {args.prefix!r}")
            keys.revoke(match[0].id)
            AuditRepository(session).add(
                who="cli", action="key.revoke", target=f"key:{args.prefix}"
            )
    finally:
        engine.dispose()
    print(f"revoked {args.prefix}", flush=True)
    return 0
