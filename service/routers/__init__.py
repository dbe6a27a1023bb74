"""The API's routers, in the order they appear in the OpenAPI document."""

from __future__ import annotations

from fastapi import APIRouter

from service.routers import (
    admin,
    alarms,
    campaigns,
    dashboard,
    health,
    reconciliations,
    records,
    rigs,
)

ALL: tuple[APIRouter, ...] = (
    health.router,
    rigs.router,
    campaigns.router,
    records.router,
    reconciliations.router,
    alarms.router,
    admin.router,
    dashboard.router,
)
