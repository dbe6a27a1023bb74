"""Shared test helpers.

Services (PostgreSQL, RabbitMQ, Chromium) are real. Locally a missing service
skips its tests; under CI (``CI`` set) a missing service fails them loudly.
"""

from __future__ import annotations

import os

import pytest

IN_CI = bool(os.environ.get("CI"))


def service_unavailable(what: str, why: str) -> None:
    """Fail under CI, skip elsewhere, with a message saying how to start the service."""
    message = f"{what} is not reachable: {why}"
    if IN_CI:
        pytest.fail(message + " — CI must run this test against the real service", pytrace=False)
    pytest.skip(message)
