"""The API's routers, in the order they appear in the OpenAPI document."""

from __future__ import annotations

from fastapi import APIRouter

from service.routers import (
    admin,
    alarms,
    campaigns,
    dashboard,
    health,
    notifications,
    overview,
    reconciliations,
    records,
    rigs,
)

ALL: tuple[APIRouter, ...] = (
    health.router,
    rigs.router,
    overview.router,
    campaigns.router,
    records.router,
    reconciliations.router,
    alarms.router,
    notifications.router,
    admin.router,
    dashboard.router,
)
