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


COMPUTE_ONLY_FOLDERS = ("physics", "dsp", "detection")
"""Test folders that touch no service, port, queue or database. Under ``pytest -n 2 --dist
loadgroup`` (README's test command) they run on one worker while every other test runs, in
collection order as before, on the other: tests that share PostgreSQL schemas, RabbitMQ queues or
ports never run concurrently, and CI's wall time is about the longer of the two halves."""


@pytest.hookimpl(optionalhook=True)  # a hook of pytest-xdist: unknown (and unused) without it
def pytest_xdist_make_scheduler(config: pytest.Config, log: object) -> object | None:
    """The two groups above as xdist's work units. (``xdist_group`` marks added at collection do
    not reach xdist 3.8's scheduler under pytest 9.2 — it rewrites ``item._nodeid``, which pytest
    no longer reads — so the grouping is made here, from the node id's folder.)"""
    if config.getvalue("dist") != "loadgroup":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class ComputeBesideServices(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            parts = nodeid.split("/")
            folder = parts[1] if len(parts) > 2 and parts[0] == "tests" else ""
            return "compute" if folder in COMPUTE_ONLY_FOLDERS else "services"

    return ComputeBesideServices(config, log)
