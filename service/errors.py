"""The ONE place where errors become HTTP responses.

Every error body has the same shape (:class:`service.schemas.ErrorBody`)::

    {"error": {"code": "not_found", "message": "rig 'x' not found", "details": null}}

``gearwatch.floor.errors.GearwatchError`` subclasses carry their own ``http_status`` and
``code``; request validation errors become 422 ``invalid_request``; Starlette's own
HTTP errors (unknown path, wrong method) keep their status; database refusals are 422/409
(503 when the database is down). Anything else is a bug:
500 ``internal_error`` with no internals in the body, logged with its traceback.
"""

from __future__ import annotations

import logging
from typing import Any

import sqlalchemy.exc as sa_exc
from fastapi import FastAPI, Request
from fastapi.encoders import jsonable_encoder
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from sqlalchemy.exc import SQLAlchemyError
from starlette.exceptions import HTTPException as StarletteHTTPException

from gearwatch.floor.errors import GearwatchError, ServiceUnavailable, Unauthorized

logger = logging.getLogger("gearwatch.service")

_STATUS_CODES = {
    400: "bad_request",
    401: "unauthorized",
    403: "forbidden",
    404: "not_found",
    405: "method_not_allowed",
    406: "not_acceptable",
    409: "conflict",
    413: "payload_too_large",
    415: "unsupported_media_type",
    422: "invalid_request",
}


def error_response(
    status: int, code: str, message: str, details: Any = None, headers: dict[str, str] | None = None
) -> JSONResponse:
    body = {"error": {"code": code, "message": message, "details": jsonable_encoder(details)}}
    return JSONResponse(status_code=status, content=body, headers=headers)


def _gearwatch_error(_request: Request, error: Exception) -> JSONResponse:
    assert isinstance(error, GearwatchError)
    headers = {"WWW-Authenticate": "Bearer"} if isinstance(error, Unauthorized) else None
    if isinstance(error, ServiceUnavailable):
        logger.error("%s: %s", error.code, error)
        return error_response(503, error.code, str(error),
                              headers={"Retry-After": str(error.retry_after_seconds)})
    if error.http_status >= 500:
        logger.error("internal error: %s", error, exc_info=error)
        return error_response(500, error.code, "internal error")
    return error_response(error.http_status, error.code, str(error), headers=headers)


def _validation_error(_request: Request, error: Exception) -> JSONResponse:
    assert isinstance(error, RequestValidationError)
    details = [
        {"loc": list(e.get("loc", ())), "msg": e.get("msg", ""), "type": e.get("type", "")}
        for e in error.errors()
    ]
    first = details[0] if details else {"loc": [], "msg": "invalid request"}
    where = ".".join(str(p) for p in first["loc"])
    return error_response(422, "invalid_request", f"{where}: {first['msg']}", details)


def _http_error(_request: Request, error: Exception) -> JSONResponse:
    assert isinstance(error, StarletteHTTPException)
    code = _STATUS_CODES.get(error.status_code, "http_error")
    return error_response(
        error.status_code, code, str(error.detail), headers=getattr(error, "headers", None)
    )


def _database_error(_request: Request, error: Exception) -> JSONResponse:
    """Safety net: values the database refuses are the caller's (422), a unique or foreign key
    violation that validation did not foresee is a conflict (409); an unreachable database 503.
    """
    if isinstance(error, sa_exc.DataError):
        logger.warning("database refused a value: %s", error)
        return error_response(
            422, "invalid_input", "a value cannot be stored (invalid text or number)"
        )
    if isinstance(error, sa_exc.IntegrityError):
        logger.warning("integrity error: %s", error)
        return error_response(409, "conflict", "conflicts with stored data")
    if isinstance(error, sa_exc.OperationalError | sa_exc.TimeoutError):
        logger.error("database unavailable: %s", error)
        return error_response(503, "database_unavailable", "the database is not available",
                              headers={"Retry-After": str(ServiceUnavailable.retry_after_seconds)})
    return _unexpected_error(_request, error)


def _unexpected_error(_request: Request, error: Exception) -> JSONResponse:
    logger.error("unhandled error: %s", error, exc_info=error)
    return error_response(500, "internal_error", "internal error")


def install_error_handlers(app: FastAPI) -> None:
    """Register every handler on ``app``."""
    app.add_exception_handler(GearwatchError, _gearwatch_error)
    app.add_exception_handler(RequestValidationError, _validation_error)
    app.add_exception_handler(StarletteHTTPException, _http_error)
    app.add_exception_handler(SQLAlchemyError, _database_error)
    app.add_exception_handler(Exception, _unexpected_error)
