"""The service's one settings object, read from ``GEARWATCH_*`` environment variables."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Literal

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict


class Settings(BaseSettings):
    """Settings of the service and of every CLI command that touches the database.

    Each field is read from the environment variable ``GEARWATCH_<NAME>`` (e.g.
    ``GEARWATCH_DATABASE_URL``); a CLI ``--db URL`` overrides ``database_url``.
    """

    model_config = SettingsConfigDict(env_prefix="GEARWATCH_", extra="ignore")

    database_url: str = Field(
        default="sqlite:///gearwatch.db",
        description="SQLAlchemy URL; the default is a SQLite file in the working directory.",
    )
    broker_url: str = Field(
        default="amqp://guest:guest@127.0.0.1:5672/",
        description="RabbitMQ URL used when ``job_runner`` is ``broker``.",
    )
    raw_store: Path = Field(
        default=Path("./raw-store"),
        description="Root folder of the content-addressed raw record store.",
    )
    job_runner: Literal["inline", "broker"] = Field(
        default="inline",
        description="Run per-record jobs in the request (``inline``) or on Dramatiq workers.",
    )
    auto_migrate: bool = Field(
        default=True, description="Bring the database schema to the alembic head at start-up."
    )
    max_upload_bytes: int = Field(
        default=512 * 1024 * 1024, description="Largest record file accepted by an upload."
    )
    trend_cache_seconds: float = Field(
        default=1.0,
        ge=0,
        description="A cached trend answer is served without re-checking the database for "
        "this long (0: check on every request).",
    )
    api_docs: bool = Field(
        default=True,
        description="Serve the OpenAPI document and its pages (/openapi.json, /docs, /redoc) "
        "without a key; they hold no data. False removes them.",
    )
    upload_dir: Path | None = Field(
        default=None,
        description="The only folder uploads are spooled to (after the caller's key and role "
        "were checked) before the job keeps them; default ``<raw_store>/.uploads``, on the "
        "raw store's disk and never the system temp folder.",
    )

    def spool_dir(self) -> Path:
        """Where an upload's bytes may be written (:attr:`upload_dir` or its default)."""
        return self.upload_dir if self.upload_dir is not None else self.raw_store / ".uploads"


@lru_cache(maxsize=1)
def get_settings() -> Settings:
    """The process-wide settings from the environment (cached)."""
    return Settings()
