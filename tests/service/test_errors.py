"""The one error mapping: gearwatch errors, validation, database refusals, bugs."""

from __future__ import annotations

import pytest
import sqlalchemy.exc as sa_exc
from fastapi import FastAPI
from fastapi.testclient import TestClient

from gearwatch.floor import errors
from service.errors import install_error_handlers

RAISED = {
    "input": errors.InputError("bad number"),
    "manifest": errors.ManifestError("[rig] pinion_teeth: not an integer"),
    "rejected": errors.RecordRejected("too few revolutions"),
    "missing": errors.NotFound("rig 'x' not found"),
    "conflict": errors.Conflict("already acknowledged"),
    "unauthorized": errors.Unauthorized("no key"),
    "forbidden": errors.Forbidden("viewer"),
    "data": sa_exc.DataError("INSERT", {}, Exception("invalid byte sequence")),
    "integrity": sa_exc.IntegrityError("INSERT", {}, Exception("duplicate key")),
    "down": sa_exc.OperationalError("SELECT", {}, Exception("connection refused")),
    "bug": ZeroDivisionError("division by zero"),
    "gearwatch-bug": errors.GearwatchError("internal detail"),
}
EXPECTED = {
    "input": (422, "invalid_input"),
    "manifest": (422, "invalid_manifest"),
    "rejected": (422, "record_rejected"),
    "missing": (404, "not_found"),
    "conflict": (409, "conflict"),
    "unauthorized": (401, "unauthorized"),
    "forbidden": (403, "forbidden"),
    "data": (422, "invalid_input"),
    "integrity": (409, "conflict"),
    "down": (503, "database_unavailable"),
    "bug": (500, "internal_error"),
    "gearwatch-bug": (500, "internal_error"),
}


@pytest.fixture(scope="module")
def client() -> TestClient:
    app = FastAPI()
    install_error_handlers(app)

    @app.get("/raise/{name}")
    def raise_(name: str) -> None:
        raise RAISED[name]

    @app.get("/typed")
    def typed(number: int) -> int:
        return number

    return TestClient(app, raise_server_exceptions=False)


@pytest.mark.parametrize("name", sorted(RAISED))
def test_each_error_has_its_status_code_and_json_body(client: TestClient, name: str) -> None:
    response = client.get(f"/raise/{name}")
    status, code = EXPECTED[name]
    assert response.status_code == status
    body = response.json()
    assert body["error"]["code"] == code
    if status >= 500:
        # no internals leak to the caller
        assert body["error"]["message"] in {"internal error", "the database is not available"}
    else:
        assert body["error"]["message"]
    if status == 401:
        assert response.headers["www-authenticate"] == "Bearer"


def test_validation_errors_name_the_parameter(client: TestClient) -> None:
    response = client.get("/typed?number=abc")
    assert response.status_code == 422
    error = response.json()["error"]
    assert error["code"] == "invalid_request" and error["message"].startswith("query.number:")
    assert error["details"][0]["loc"] == ["query", "number"]
    missing = client.get("/nowhere")
    assert missing.status_code == 404 and missing.json()["error"]["code"] == "not_found"
