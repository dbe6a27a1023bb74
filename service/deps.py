"""Request dependencies: settings, a database session, the caller's API key and role checks."""

from __future__ import annotations

import datetime as dt
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass
from typing import Annotated

from fastapi import Depends, Request
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from sqlalchemy.orm import Session

from gearwatch.floor.errors import Forbidden, Unauthorized
from gearwatch.floor.settings import Settings
from gearwatch.usecases.keys import verify_api_key
from storage.models import utcnow

ROLE_RANK = {"viewer": 0, "operator": 1, "admin": 2}
LAST_USED_RESOLUTION = dt.timedelta(minutes=1)

_bearer = HTTPBearer(
    auto_error=False,
    description="An API key from `gearwatch keys create`, sent as `Authorization: Bearer <key>`.",
)


def get_settings(request: Request) -> Settings:
    settings: Settings = request.app.state.settings
    return settings


async def get_db(request: Request) -> AsyncIterator[Session]:
    """One session per request. Handlers that write call ``commit()`` themselves; whatever
    is left uncommitted (an error half-way) is rolled back here.

    Asynchronous on purpose: the clean-up then runs on the event loop, not in the request
    thread pool, so a full pool can never keep connections from being returned."""
    session: Session = request.app.state.session_factory()
    try:
        yield session
    finally:
        session.rollback()
        session.close()


SettingsDep = Annotated[Settings, Depends(get_settings)]
DbSession = Annotated[Session, Depends(get_db)]


@dataclass(frozen=True)
class Caller:
    """Who is calling: the API key's id, prefix, name and role."""

    key_id: int
    prefix: str
    name: str
    role: str

    @property
    def who(self) -> str:
        """How the audit log and acknowledgements name the caller."""
        return f"{self.name} ({self.prefix})" if self.name else f"key {self.prefix}"


def get_current_key(
    db: DbSession,
    credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)],
) -> Caller:
    if credentials is None or credentials.scheme.lower() != "bearer" or not credentials.credentials:
        raise Unauthorized("an API key is required: Authorization: Bearer <key>")
    key = verify_api_key(db, credentials.credentials, touch=False)
    if key is None:
        raise Unauthorized("unknown or revoked API key")
    caller = Caller(key_id=key.id, prefix=key.prefix, name=key.name, role=key.role)
    # last_used_at is bookkeeping, kept to the minute: a write per request would serialise
    # every reader on SQLite. Committed now, apart from whatever the handler does.
    now = utcnow()
    if key.last_used_at is None or now - key.last_used_at > LAST_USED_RESOLUTION:
        key.last_used_at = now
        db.commit()
    else:
        # End the transaction either way: its connection goes back to the pool while the
        # request waits for a thread to run its handler, so threads can never all be waiting
        # for connections held by requests that are waiting for threads.
        db.rollback()
    return caller


CurrentKey = Annotated[Caller, Depends(get_current_key)]


def require_role(role: str) -> Callable[[Caller], Caller]:
    """A dependency that lets through keys of ``role`` or a higher one, else 403."""
    needed = ROLE_RANK[role]

    def check(caller: CurrentKey) -> Caller:
        if ROLE_RANK.get(caller.role, -1) < needed:
            raise Forbidden(f"this needs the {role} role (the key's role is {caller.role})")
        return caller

    return check


OperatorKey = Annotated[Caller, Depends(require_role("operator"))]
AdminKey = Annotated[Caller, Depends(require_role("admin"))]
