"""docker-compose.yml and Dockerfile structure (no container engine here: the YAML is
checked for what `docker compose config` would need and what the deployment promises)."""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[2]


def load_compose() -> dict:
    data = yaml.safe_load((ROOT / "docker-compose.yml").read_text())
    assert isinstance(data, dict)
    return data


def test_compose_services_volumes_and_replicas() -> None:
    compose = load_compose()
    services = compose["services"]
    assert set(services) == {"postgres", "rabbitmq", "api", "worker"}
    assert services["worker"]["deploy"]["replicas"] == 2
    assert "raw-store" in compose["volumes"]
    for name in ("api", "worker"):
        service = services[name]
        assert "raw-store:/data/raw-store" in service["volumes"]
        env = service["environment"]
        assert env["GEARWATCH_RAW_STORE"] == "/data/raw-store"
        assert env["GEARWATCH_DATABASE_URL"].startswith("postgresql+psycopg://")
        assert "@postgres:5432/" in env["GEARWATCH_DATABASE_URL"]
        assert (
            env["GEARWATCH_BROKER_URL"].startswith("amqp://")
            and "@rabbitmq:5672" in env["GEARWATCH_BROKER_URL"]
        )
        assert services[name]["depends_on"]["postgres"]["condition"] == "service_healthy"
    assert services["api"]["ports"] == ["8000:8000"]
    assert services["api"]["command"][:2] == ["gearwatch", "serve"]
    assert "0.0.0.0" in services["api"]["command"]
    for name in ("postgres", "rabbitmq", "api"):
        assert services[name]["healthcheck"]["test"]
    worker = services["worker"]["command"]
    assert worker[:2] == ["dramatiq", "gearwatch.worker"]
    assert importlib.util.find_spec(worker[1]) is not None  # the actor module exists
    assert services["worker"]["environment"]["GEARWATCH_JOB_RUNNER"] == "broker"
    # one migration at a time: the api migrates at start-up, the workers wait until it is healthy
    assert services["worker"]["depends_on"]["api"]["condition"] == "service_healthy"
    assert "/health" in " ".join(services["api"]["healthcheck"]["test"])


def test_compose_references_are_defined() -> None:
    compose = load_compose()
    declared = set(compose.get("volumes") or {})
    for name, service in compose["services"].items():
        for volume in service.get("volumes", []):
            source = volume.split(":")[0]
            if not source.startswith((".", "/")):
                assert source in declared, (name, source)
        for dependency in service.get("depends_on", {}):
            assert dependency in compose["services"], (name, dependency)
        assert "image" in service or "build" in service


def test_dockerfile_installs_the_package_and_serves_on_8000() -> None:
    text = (ROOT / "Dockerfile").read_text()
    assert re.search(r"^FROM python:3\.11", text, re.M)
    assert "pip install" in text and "EXPOSE 8000" in text
    assert re.search(r'^CMD \["gearwatch", "serve", "--host", "0.0.0.0"', text, re.M)
    assert "USER gearwatch" in text  # not root
