"""API keys and the audit log (admin role)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Path, Query

from gearwatch.usecases.keys import issue_api_key
from service import schemas
from service.deps import AdminKey, DbSession
from service.routers.common import Limit, Offset, errors
from storage.repositories import ApiKeyRepository, AuditRepository

router = APIRouter(prefix="/api/v1", tags=["admin"])

KeyId = Annotated[int, Path(ge=1, le=2**31 - 1, description="API key id.")]


def _key_out(key: object) -> schemas.ApiKeyOut:
    return schemas.ApiKeyOut.model_validate(key, from_attributes=True)


@router.get(
    "/keys",
    response_model=schemas.ApiKeyList,
    summary="List API keys (never the keys themselves)",
    responses=errors(401, 403, 422),
)
def list_keys(
    db: DbSession,
    _caller: AdminKey,
    include_revoked: Annotated[bool, Query(description="Also revoked keys.")] = False,
) -> schemas.ApiKeyList:
    keys = ApiKeyRepository(db).list(include_revoked=include_revoked)
    return schemas.ApiKeyList(items=[_key_out(k) for k in keys])


@router.post(
    "/keys",
    response_model=schemas.ApiKeyCreated,
    status_code=201,
    summary="Create an API key; the key is in this answer only",
    responses=errors(401, 403, 422),
)
def create_key(
    body: schemas.ApiKeyCreate, db: DbSession, caller: AdminKey
) -> schemas.ApiKeyCreated:
    key, plaintext = issue_api_key(db, name=body.name, role=body.role)
    AuditRepository(db).add(
        who=caller.who,
        action="key.create",
        target=f"key:{key.prefix}",
        details={"role": body.role, "name": body.name},
    )
    db.commit()
    return schemas.ApiKeyCreated(**_key_out(key).model_dump(), key=plaintext)


@router.delete(
    "/keys/{key_id}",
    response_model=schemas.ApiKeyOut,
    summary="Revoke an API key",
    responses=errors(401, 403, 404, 422),
)
def revoke_key(key_id: KeyId, db: DbSession, caller: AdminKey) -> schemas.ApiKeyOut:
    key = ApiKeyRepository(db).revoke(key_id)
    AuditRepository(db).add(who=caller.who, action="key.revoke", target=f"key:{key.prefix}")
    db.commit()
    return _key_out(key)


@router.get(
    "/audit",
    response_model=schemas.AuditList,
    summary="The audit log, newest first",
    responses=errors(401, 403, 422),
)
def audit(
    db: DbSession,
    _caller: AdminKey,
    action: Annotated[
        str | None, Query(min_length=1, max_length=100, pattern=schemas.NAME_PATTERN)
    ] = None,
    limit: Limit = 100,
    offset: Offset = 0,
) -> schemas.AuditList:
    rows = AuditRepository(db).list(action=action, limit=limit, offset=offset)
    return schemas.AuditList(
        items=[schemas.AuditOut.model_validate(r, from_attributes=True) for r in rows]
    )
