"""Prometheus metrics of the gateway (`GET /metrics`), from what its client already receives.

The node keeps no web stack: the tasks' counts and durations come from the task events the
gateway's TaskManagerClient receives (so they count from the gateway's start), the active,
paused and queued counts from its latest active task list and the schedules' runs and misses
from /task_manager/get_schedules, both read when scraped. The gateway's own requests are
counted by an ASGI middleware (request_metrics.py). Every gateway has a registry of its own
(never the global one).
"""

import contextlib
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

from prometheus_client import CollectorRegistry, Counter, Gauge, Histogram
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily, Metric
from prometheus_client.registry import Collector

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
from task_manager_web.request_metrics import RequestCounts

UNKNOWN_TASK_LABEL = '(unknown)'
"""The task_name label of a task refused as unknown: a request cannot add label values."""
DURATION_BUCKETS_SEC = (0.1, 0.5, 1, 2.5, 5, 10, 30, 60, 120, 300, 600, 1800, 3600)
SCRAPE_TIMEOUT_SEC = 2.0
"""The longest a scrape waits for each answer of the Task Manager; without it, left out."""


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
        self.request_counts = RequestCounts(self.registry, 'task_manager_web', 'the gateway')
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
