"""Property-based fuzzing of the whole OpenAPI document with schemathesis (on SQLite and
PostgreSQL): no request — valid or invalid, on real or random ids — gets a 5xx.

Every operation is driven with schema-conforming (positive) and schema-violating (negative)
cases, half of them aimed at the seeded rig, campaign, record and alarm so that handlers run
past their 404s. Deterministic (``derandomize``) so a failure reproduces.
"""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.errors import Unsatisfiable

from tests.service.conftest import Api
from tests.service.seed import seed_campaign

EXAMPLES_PER_OPERATION_AND_MODE = 8
"""Per operation, positive and negative: 8 keeps the two backends under 30 s of CI together;
the long run is `GEARWATCH_FUZZ_EXAMPLES`-sized fuzzing of the upload route (tests/fuzz)."""


@pytest.mark.slow
def test_schemathesis_finds_no_server_error(api: Api) -> None:
    import schemathesis
    from schemathesis import GenerationMode

    from service.app import create_app

    with api.session() as session:
        seeded = seed_campaign(session)
        session.commit()
        from storage.repositories import AlarmRepository

        alarm_id = AlarmRepository(session).list(limit=1)[0].id
    known = {
        "rig_id": "rig-a",
        "campaign_id": "camp-a",
        "record_id": seeded.record_ids[-1],
        "alarm_id": alarm_id,
        "indicator": "mci_depth",
    }
    # A separate app instance: schemathesis runs its own lifespan for the apps it drives.
    app = create_app(api.app.state.settings)
    schema = schemathesis.openapi.from_asgi("/openapi.json", app)
    admin = api.headers("admin")
    admin_id = next(
        k["id"] for k in api.get("/api/v1/keys", "admin").json()["items"] if k["role"] == "admin"
    )
    server_errors: list[str] = []
    operations = exercised = 0
    for result in schema.get_all_operations():
        operation = result.ok()
        operations += 1
        path_names = {p.name for p in operation.path_parameters}
        hints = {k: v for k, v in known.items() if k in path_names}
        for mode in (GenerationMode.POSITIVE, GenerationMode.NEGATIVE):
            strategy = operation.as_strategy(generation_mode=mode)
            if hints and mode is GenerationMode.POSITIVE:
                strategy = st.one_of(
                    strategy, operation.as_strategy(generation_mode=mode, path_parameters=hints)
                )
            if "key_id" in path_names:  # revoking the key the run uses would end the run
                strategy = strategy.filter(lambda case: case.path_parameters["key_id"] != admin_id)

            @settings(
                max_examples=EXAMPLES_PER_OPERATION_AND_MODE,
                deadline=None,
                derandomize=True,
                database=None,
                suppress_health_check=list(HealthCheck),
            )
            @given(case=strategy)
            def exercise(case: Any) -> None:
                response = case.call(headers=admin)
                if response.status_code >= 500:
                    server_errors.append(
                        f"{case.method} {case.formatted_path} -> {response.status_code}: "
                        f"{response.text[:300]} (query={case.query!r}, body={case.body!r:.200})"
                    )
                elif response.status_code >= 400 and response.status_code != 405:
                    body = response.json()
                    assert set(body) == {"error"}, response.text

            try:
                exercise()
            except Unsatisfiable:
                # nothing to violate: an operation without parameters or body
                assert mode is GenerationMode.NEGATIVE, operation.label
                continue
            exercised += 1
    assert operations >= 20 and exercised >= 40
    assert not server_errors, "\n".join(server_errors[:20])
