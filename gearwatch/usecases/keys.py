"""API keys: their format, generation and check; create one in a database.

A key looks like ``gw_<prefix>_<secret>``: the prefix (8 hex digits) finds the stored row, and
only the sha256 of the whole key is stored (:class:`storage.repositories.ApiKeyRepository`); a
constant-time comparison checks it. The plaintext is shown once, when the key is created.
"""

from __future__ import annotations

import hashlib
import hmac
import secrets

from sqlalchemy.orm import Session

from storage.db import open_database, session_scope
from storage.models import ApiKey
from storage.repositories import ApiKeyRepository, AuditRepository

API_KEY_PREFIX = "gw"


def _hash_key(plaintext: str) -> str:
    return hashlib.sha256(plaintext.encode()).hexdigest()


def issue_api_key(session: Session, *, name: str, role: str) -> tuple[ApiKey, str]:
    """A new key; returns the row and the plaintext key (shown once, never stored)."""
    keys = ApiKeyRepository(session)
    prefix = secrets.token_hex(4)
    while keys.prefix_taken(prefix):
        prefix = secrets.token_hex(4)
    plaintext = f"{API_KEY_PREFIX}_{prefix}_{secrets.token_urlsafe(32)}"
    key = keys.add(prefix=prefix, key_sha256=_hash_key(plaintext), name=name, role=role)
    return key, plaintext


def verify_api_key(session: Session, plaintext: str, *, touch: bool = True) -> ApiKey | None:
    """The active key matching ``plaintext``, or ``None``; ``touch`` updates ``last_used_at``."""
    parts = plaintext.split("_", 2)
    if len(parts) != 3 or parts[0] != API_KEY_PREFIX:
        return None
    keys = ApiKeyRepository(session)
    key = keys.active_by_prefix(parts[1])
    if key is None:
        return None
    if not hmac.compare_digest(key.key_sha256, _hash_key(plaintext)):
        return None
    if touch:
        keys.touch(key)
    return key


def create_api_key(database_url: str, *, role: str, name: str, who: str = "cli") -> str:
    """Create an API key (audited as created by ``who``) and return its plaintext, shown once."""
    engine, factory = open_database(database_url)
    try:
        with session_scope(factory) as session:
            key, plaintext = issue_api_key(session, role=role, name=name)
            AuditRepository(session).add(
                who=who,
                action="key.create",
                target=f"key:{key.prefix}",
                details={"role": role, "name": name},
            )
    finally:
        engine.dispose()
    return str(plaintext)
