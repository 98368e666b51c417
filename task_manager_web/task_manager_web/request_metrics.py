"""The requests of a door as Prometheus metrics: an ASGI middleware that counts each request by
route, method and status and times it to its answer's head; and the answer of GET /metrics.
Shared by the web gateway and the fleet console (no rclpy here), each with its own registry
and metric names."""

import time
from typing import Any

from fastapi import Response
from prometheus_client import (
    CONTENT_TYPE_LATEST,
    CollectorRegistry,
    Counter,
    Histogram,
    generate_latest,
)
from starlette.types import ASGIApp, Message, Receive, Scope, Send

UNMATCHED_ROUTE = '(unmatched)'
"""The route label of a request that reached no route (404, or refused before routing)."""
METHODS = frozenset({'GET', 'HEAD', 'POST', 'PUT', 'PATCH', 'DELETE', 'OPTIONS'})
"""Methods named in the method label; any other is `OTHER` (a request cannot add values)."""
REQUEST_BUCKETS_SEC = (0.001, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10, 30)
METRICS_ROUTE: dict[str, Any] = {
    'tags': ['state'],
    'response_class': Response,
    'responses': {200: {'content': {CONTENT_TYPE_LATEST: {}}}},
}
"""What the route of GET /metrics answers, for its OpenAPI description."""


def metrics_response(registry: CollectorRegistry) -> Response:
    """Every metric of `registry`, in Prometheus' text format."""
    return Response(generate_latest(registry), media_type=CONTENT_TYPE_LATEST)


class RequestCounts:
    """`<prefix>_requests_total` and `<prefix>_request_duration_seconds` in `registry`."""

    def __init__(self, registry: CollectorRegistry, prefix: str, door: str) -> None:
        """`door`: what answers, in the metrics' help (`the gateway`)."""
        self.requests = Counter(
            f'{prefix}_requests',
            f'HTTP requests answered by {door}, by route, method and status.',
            ['route', 'method', 'status'],
            registry=registry,
        )
        self.request_duration = Histogram(
            f'{prefix}_request_duration_seconds',
            "Time from a request to its answer's head (an event stream: until it opened).",
            ['route', 'method'],
            buckets=REQUEST_BUCKETS_SEC,
            registry=registry,
        )

    def request_done(self, route: str, method: str, status: int, duration_sec: float) -> None:
        self.requests.labels(route, method, str(status)).inc()
        self.request_duration.labels(route, method).observe(duration_sec)


class RequestMetrics:
    """An ASGI middleware: counts each request and times it to its answer's head."""

    def __init__(self, app: ASGIApp, counts: RequestCounts) -> None:
        self.app = app
        self.counts = counts

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope['type'] != 'http':
            await self.app(scope, receive, send)
            return
        began = time.perf_counter()

        async def send_counted(message: Message) -> None:
            if message['type'] == 'http.response.start':
                # the router puts the matched route into the scope (a template: few values)
                route = getattr(scope.get('route'), 'path', None) or UNMATCHED_ROUTE
                method = scope['method'] if scope['method'] in METHODS else 'OTHER'
                duration_sec = time.perf_counter() - began
                self.counts.request_done(route, method, message['status'], duration_sec)
            await send(message)

        await self.app(scope, receive, send_counted)
