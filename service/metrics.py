"""Prometheus metrics in the text exposition format (version 0.0.4), written by hand.

Two families are kept in memory per process: a request counter and a request
duration histogram, both labelled by method, route template (never the raw path,
so ids do not explode the label space) and status code. Gauges read from the
database at scrape time are appended by the ``/metrics`` route.
"""

from __future__ import annotations

import threading
import time
from collections import defaultdict
from collections.abc import Iterable

from starlette.types import ASGIApp, Message, Receive, Scope, Send

DURATION_BUCKETS_S = (0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0)

LabelKey = tuple[str, str, str]


def _escape(value: str) -> str:
    return value.replace("\\", "\\\\").replace("\n", "\\n").replace('"', '\\"')


def _labels(pairs: Iterable[tuple[str, str]]) -> str:
    inner = ",".join(f'{name}="{_escape(value)}"' for name, value in pairs)
    return "{" + inner + "}" if inner else ""


class RequestMetrics:
    """Thread-safe request counters and duration histograms."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._count: dict[LabelKey, int] = defaultdict(int)
        self._bucket_counts: dict[LabelKey, list[int]] = {}
        self._sum_s: dict[LabelKey, float] = defaultdict(float)

    def observe(self, method: str, route: str, status: int, duration_s: float) -> None:
        key = (method, route, str(status))
        with self._lock:
            self._count[key] += 1
            self._sum_s[key] += duration_s
            buckets = self._bucket_counts.setdefault(key, [0] * len(DURATION_BUCKETS_S))
            for i, upper in enumerate(DURATION_BUCKETS_S):
                if duration_s <= upper:
                    buckets[i] += 1

    def render(self) -> str:
        lines = [
            "# HELP gearwatch_http_requests_total HTTP requests handled.",
            "# TYPE gearwatch_http_requests_total counter",
        ]
        with self._lock:
            keys = sorted(self._count)
            for key in keys:
                lines.append(
                    f"gearwatch_http_requests_total{_labels(self._label_pairs(key))} "
                    f"{self._count[key]}"
                )
            lines += [
                "# HELP gearwatch_http_request_duration_seconds Time to handle a request.",
                "# TYPE gearwatch_http_request_duration_seconds histogram",
            ]
            for key in keys:
                pairs = self._label_pairs(key)
                for upper, n in zip(DURATION_BUCKETS_S, self._bucket_counts[key], strict=True):
                    lines.append(
                        "gearwatch_http_request_duration_seconds_bucket"
                        f"{_labels([*pairs, ('le', repr(upper))])} {n}"
                    )
                lines.append(
                    "gearwatch_http_request_duration_seconds_bucket"
                    f"{_labels([*pairs, ('le', '+Inf')])} {self._count[key]}"
                )
                lines.append(
                    f"gearwatch_http_request_duration_seconds_sum{_labels(pairs)} "
                    f"{self._sum_s[key]:.6f}"
                )
                lines.append(
                    f"gearwatch_http_request_duration_seconds_count{_labels(pairs)} "
                    f"{self._count[key]}"
                )
        return "\n".join(lines) + "\n"

    @staticmethod
    def _label_pairs(key: LabelKey) -> list[tuple[str, str]]:
        return [("method", key[0]), ("route", key[1]), ("status", key[2])]


def gauge_lines(name: str, help_text: str, samples: Iterable[tuple[dict[str, str], float]]) -> str:
    """One gauge family in text format."""
    lines = [f"# HELP {name} {help_text}", f"# TYPE {name} gauge"]
    for labels, value in samples:
        lines.append(f"{name}{_labels(sorted(labels.items()))} {value:g}")
    return "\n".join(lines) + "\n"


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
