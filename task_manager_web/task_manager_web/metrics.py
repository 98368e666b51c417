"""Prometheus metrics of the gateway (`GET /metrics`), from what its client already receives.

The node keeps no web stack: the tasks' counts and durations come from the task events the
gateway's TaskManagerClient receives (so they count from the gateway's start), the active,
paused and queued counts from its latest active task list and the schedules' runs and misses
from /task_manager/get_schedules, both read when scraped. The gateway's own requests are
counted by an ASGI middleware. Every gateway has a registry of its own (never the global one).
"""

import contextlib
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

from prometheus_client import CollectorRegistry, Counter, Gauge, Histogram
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily, Metric
from prometheus_client.registry import Collector
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from task_manager.client import (
    ActiveTaskInfo,
    ScheduleInfo,
    TaskEvent,
    TaskEventKind,
    TaskManagerClient,
)
from task_manager.core.errors import TaskManagerError
from task_manager.core.status import ErrorCode, TaskStatus
from task_manager_web.node_link import NodeLink

UNKNOWN_TASK_LABEL = '(unknown)'
"""The task_name label of a task refused as unknown: a request cannot add label values."""
UNMATCHED_ROUTE = '(unmatched)'
"""The route label of a request that reached no route (404, or refused before routing)."""
DURATION_BUCKETS_SEC = (0.1, 0.5, 1, 2.5, 5, 10, 30, 60, 120, 300, 600, 1800, 3600)
METHODS = frozenset({'GET', 'HEAD', 'POST', 'PUT', 'PATCH', 'DELETE', 'OPTIONS'})
"""Methods named in the method label; any other is `OTHER` (a request cannot add values)."""
SCRAPE_TIMEOUT_SEC = 2.0
"""The longest a scrape waits for each answer of the Task Manager; without it, left out."""
REQUEST_BUCKETS_SEC = (0.001, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10, 30)


@dataclass(frozen=True)
class NodeSnapshot:
    """What the Task Manager reported when scraped; None: not known (no node, no answer)."""

    active: Sequence[ActiveTaskInfo] | None = None
    schedules: Sequence[ScheduleInfo] | None = None


class _NodeCollector(Collector):
    """The Task Manager's state at the scrape: its active tasks and its schedules."""

    def __init__(self) -> None:
        self.snapshot = NodeSnapshot()

    def describe(self) -> Iterable[Metric]:
        return []

    def collect(self) -> Iterable[Metric]:
        active = self.snapshot.active
        if active is not None:
            counts = {
                'task_manager_active_tasks': ('Active tasks (queued, running or paused).', None),
                'task_manager_paused_tasks': ('Active tasks paused.', TaskStatus.PAUSED),
                'task_manager_queued_tasks': ('Active tasks queued.', TaskStatus.QUEUED),
            }
            for name, (documentation, status) in counts.items():
                value = sum(1 for t in active if status is None or t.status == status)
                yield GaugeMetricFamily(name, documentation, value=value)
        schedules = self.snapshot.schedules
        if schedules is not None:
            labels = ['schedule_id', 'task_name']
            runs = CounterMetricFamily(
                'task_manager_schedule_runs', 'Runs each schedule started.', labels=labels
            )
            misses = CounterMetricFamily(
                'task_manager_schedule_misses',
                'Due times of each schedule not run (too late, or coalesced).',
                labels=labels,
            )
            for schedule in schedules:
                label_values = [schedule.schedule_id, schedule.task_name]
                runs.add_metric(label_values, schedule.run_count)
                misses.add_metric(label_values, schedule.missed_count)
            yield runs
            yield misses


class GatewayMetrics:
    """The metrics of one gateway, in a CollectorRegistry of its own."""

    def __init__(self) -> None:
        self.registry = CollectorRegistry()
        self.tasks_ended = Counter(
            'task_manager_tasks_ended',
            'Tasks ended since the gateway started, by task name and final status.',
            ['task_name', 'status'],
            registry=self.registry,
        )
        self.task_duration = Histogram(
            'task_manager_task_duration_seconds',
            'Running time of the tasks ended (from start to end, less the time paused).',
            ['task_name'],
            buckets=DURATION_BUCKETS_SEC,
            registry=self.registry,
        )
        self.connected = Gauge(
            'task_manager_web_connected',
            '1 while the gateway reaches a Task Manager, else 0.',
            registry=self.registry,
        )
        self.requests = Counter(
            'task_manager_web_requests',
            'HTTP requests answered by the gateway, by route, method and status.',
            ['route', 'method', 'status'],
            registry=self.registry,
        )
        self.request_duration = Histogram(
            'task_manager_web_request_duration_seconds',
            "Time from a request to its answer's head (an event stream: until it opened).",
            ['route', 'method'],
            buckets=REQUEST_BUCKETS_SEC,
            registry=self.registry,
        )
        self._node = _NodeCollector()
        self.registry.register(self._node)

    def watch(self, client: TaskManagerClient) -> Callable[[], None]:
        """Count the tasks that end from now on; returns the unsubscribe."""
        return client.on_task_event(self.on_task_event)

    def on_task_event(self, event: TaskEvent) -> None:
        """From the client's executor thread (prometheus_client's metrics are thread-safe)."""
        if event.kind != TaskEventKind.ENDED:
            return
        task = event.task
        unknown = task.error_code == ErrorCode.UNKNOWN_TASK
        task_name = UNKNOWN_TASK_LABEL if unknown else task.task_name
        self.tasks_ended.labels(task_name, str(task.status)).inc()
        elapsed = task.elapsed()
        if elapsed is not None:
            self.task_duration.labels(task_name).observe(elapsed.total_seconds())

    def set_node(self, connected: bool, snapshot: NodeSnapshot) -> None:
        """What the next exposition says of the Task Manager."""
        self.connected.set(1 if connected else 0)
        self._node.snapshot = snapshot

    def request_done(self, route: str, method: str, status: int, duration_sec: float) -> None:
        self.requests.labels(route, method, str(status)).inc()
        self.request_duration.labels(route, method).observe(duration_sec)


class RequestMetrics:
    """An ASGI middleware: counts each request and times it to its answer's head."""

    def __init__(self, app: ASGIApp, metrics: GatewayMetrics) -> None:
        self.app = app
        self.metrics = metrics

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
                self.metrics.request_done(route, method, message['status'], duration_sec)
            await send(message)

        await self.app(scope, receive, send_counted)


async def node_snapshot(link: NodeLink) -> NodeSnapshot:
    """The active task list (the client's latest) and the schedules (one service call); each
    None when the Task Manager does not give it within SCRAPE_TIMEOUT_SEC."""
    if not link.connected:
        return NodeSnapshot()
    active: list[ActiveTaskInfo] | None = None
    schedules: list[ScheduleInfo] | None = None
    with contextlib.suppress(TaskManagerError):
        active = await link.read(link.client.active_tasks, SCRAPE_TIMEOUT_SEC)
    with contextlib.suppress(TaskManagerError):
        schedules = await link.read(link.client.schedules, None, SCRAPE_TIMEOUT_SEC)
    return NodeSnapshot(active, schedules)
