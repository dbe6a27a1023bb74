"""API keys: stored hashed, found by prefix."""

from __future__ import annotations

import builtins

import sqlalchemy as sa

from gearwatch.floor.errors import InputError
from storage.models import (
    ROLES,
    ApiKey,
    utcnow,
)
from storage.repositories.base import Repository


class ApiKeyRepository(Repository[ApiKey]):
    """Stored API keys: only the sha256 of the whole key is kept, with the prefix that finds the
    row. The key's format, its generation and its check are the use-case's
    (:mod:`gearwatch.usecases.keys`)."""

    model = ApiKey
    noun = "API key"

    def prefix_taken(self, prefix: str) -> bool:
        return bool(self.session.scalar(sa.select(ApiKey.id).where(ApiKey.prefix == prefix)))

    def add(self, *, prefix: str, key_sha256: str, name: str, role: str) -> ApiKey:
        """A new key row (its plaintext is never stored)."""
        if role not in ROLES:
            raise InputError(f"unknown role {role!r} (known: {', '.join(ROLES)})")
        key = ApiKey(prefix=prefix, key_sha256=key_sha256, name=name, role=role)
        self.session.add(key)
        self.session.flush()
        return key

    def active_by_prefix(self, prefix: str) -> ApiKey | None:
        """The key of that prefix unless it is revoked."""
        key = self.session.scalar(sa.select(ApiKey).where(ApiKey.prefix == prefix))
        if key is None or key.revoked_at is not None:
            return None
        return key

    def touch(self, key: ApiKey) -> None:
        """Record that ``key`` was just used."""
        key.last_used_at = utcnow()
        self.session.flush()

    def list(self, *, include_revoked: bool = False) -> builtins.list[ApiKey]:
        query = sa.select(ApiKey).order_by(ApiKey.id)
        if not include_revoked:
            query = query.where(ApiKey.revoked_at.is_(None))
        return list(self.session.scalars(query))

    def revoke(self, key_id: int) -> ApiKey:
        key = self.get(key_id)
        if key.revoked_at is None:
            key.revoked_at = utcnow()
            self.session.flush()
        return key

    def set_role(self, key_id: int, role: str) -> ApiKey:
        if role not in ROLES:
            raise InputError(f"unknown role {role!r} (known: {', '.join(ROLES)})")
        key = self.get(key_id)
        key.role = role
        self.session.flush()
        return key

    def count(self) -> int:
        return int(self.session.scalar(sa.select(sa.func.count(ApiKey.id))) or 0)
