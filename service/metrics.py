"""Prometheus metrics (``prometheus_client``), in the text exposition format.

Two families are kept in memory per application, in a registry of its own: a request counter
and a request duration histogram, both labelled by method, route template (never the raw path,
so ids do not explode the label space) and status code. Gauges read from the database at
scrape time are appended by the ``/metrics`` route (:func:`gauge_lines`).
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Iterator

from prometheus_client import CollectorRegistry, Counter, Histogram, generate_latest
from prometheus_client.core import GaugeMetricFamily, Metric
from starlette.types import ASGIApp, Message, Receive, Scope, Send

DURATION_BUCKETS_S = (0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0)

LABELS = ("method", "route", "status")


class RequestMetrics:
    """Request counters and duration histograms of one application (thread-safe)."""

    def __init__(self) -> None:
        self.registry = CollectorRegistry(auto_describe=False)
        self._requests = Counter(
            "gearwatch_http_requests", "HTTP requests handled.", LABELS, registry=self.registry
        )
        self._duration = Histogram(
            "gearwatch_http_request_duration_seconds", "Time to handle a request.", LABELS,
            buckets=DURATION_BUCKETS_S, registry=self.registry,
        )

    def observe(self, method: str, route: str, status: int, duration_s: float) -> None:
        labels = (method, route, str(status))
        self._requests.labels(*labels).inc()
        self._duration.labels(*labels).observe(duration_s)

    def render(self) -> str:
        return generate_latest(self.registry).decode("utf-8")


class _Families:
    """A collector of families built at scrape time."""

    def __init__(self, families: list[Metric]) -> None:
        self.families = families

    def collect(self) -> Iterator[Metric]:
        return iter(self.families)


def gauge_lines(name: str, help_text: str, samples: Iterable[tuple[dict[str, str], float]]) -> str:
    """One gauge family in text format (values read at scrape time)."""
    samples = list(samples)
    names = sorted({key for labels, _ in samples for key in labels})
    family = GaugeMetricFamily(name, help_text, labels=names)
    for labels, value in samples:
        family.add_metric([labels.get(key, "") for key in names], value)
    registry = CollectorRegistry(auto_describe=False)
    registry.register(_Families([family]))
    return generate_latest(registry).decode("utf-8")


def route_template(scope: Scope) -> str:
    """The matched route's path template (``/api/v1/rigs/{rig_id}``), or ``unmatched``.

    Starlette's router leaves the matched route in ``scope["route"]``.
    """
    route = scope.get("route")
    return str(getattr(route, "path", "unmatched")) if route is not None else "unmatched"


class MetricsMiddleware:
    """Pure ASGI middleware (no body buffering) recording every HTTP request."""

    def __init__(self, app: ASGIApp, metrics: RequestMetrics) -> None:
        self.app = app
        self.metrics = metrics

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        started = time.perf_counter()
        status = 500

        async def send_wrapper(message: Message) -> None:
            nonlocal status
            if message["type"] == "http.response.start":
                status = int(message["status"])
            await send(message)

        try:
            await self.app(scope, receive, send_wrapper)
        finally:
            self.metrics.observe(
                scope["method"], route_template(scope), status, time.perf_counter() - started
            )
