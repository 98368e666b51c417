"""Prometheus metrics of the console (`GET /metrics`): each robot's series, the fleet history's,
and the console's own requests, in a registry of its own (never the global one).

A robot's state is read from the Fleet when scraped (its connection, active, queued and paused
tasks, results stored and bad messages since the console started); the tasks ended are counted
as their results are stored (each once), by robot and status.
"""

from collections.abc import Iterable

from prometheus_client import CollectorRegistry, Counter
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily, Metric
from prometheus_client.registry import Collector
from task_manager_web.request_metrics import RequestCounts

from task_manager_console.fleet import Change, Fleet
from task_manager_console.robots import ConnectionState

PREFIX = 'task_manager_console'
FINAL_STATUSES = frozenset({'DONE', 'ERROR', 'CANCELED'})
OTHER_STATUS = '(other)'
"""The status label of a result whose status is none of FINAL_STATUSES: a robot's message
cannot add label values."""
ROBOT = ['robot_id']


class _FleetCollector(Collector):
    """The robots and the fleet history as the Fleet knows them when scraped."""

    def __init__(self, fleet: Fleet) -> None:
        self.fleet = fleet

    def describe(self) -> Iterable[Metric]:
        return []

    def collect(self) -> Iterable[Metric]:
        robots = sorted(self.fleet.robots.values(), key=lambda robot: robot.robot_id)
        yield GaugeMetricFamily(f'{PREFIX}_robots', 'Robots seen on the broker.', len(robots))
        connection = GaugeMetricFamily(
            f'{PREFIX}_robot_connection',
            "Each robot's connection state: 1 for the state it is in, 0 for the others.",
            labels=[*ROBOT, 'state'],
        )
        gauges = {
            name: GaugeMetricFamily(f'{PREFIX}_robot_{name}', text, labels=ROBOT)
            for name, text in (
                ('online', '1 while the robot is ONLINE and reaches its Task Manager, else 0.'),
                ('silent', '1 while the robot is silent (its bridge vanished, or reaches no '
                 'Task Manager), else 0.'),
                ('active_tasks', "The robot's active tasks (queued, running or paused)."),
                ('queued_tasks', "The robot's active tasks queued."),
                ('paused_tasks', "The robot's active tasks paused."),
            )
        }  # fmt: skip
        counters = {
            name: CounterMetricFamily(f'{PREFIX}_robot_{name}', text, labels=ROBOT)
            for name, text in (
                ('results_stored', "The robot's results stored since the console started."),
                ('bad_messages', "The robot's messages ignored (not fitting the protocol)."),
            )
        }
        for robot in robots:
            labels = [robot.robot_id]
            for state in ConnectionState:
                value = 1 if robot.connection_state == state else 0
                connection.add_metric([robot.robot_id, str(state)], value)
            statuses = [task.get('status') for task in robot.active]
            values = {
                'online': int(robot.online),
                'silent': int(robot.silent),
                'active_tasks': len(robot.active) + robot.active_omitted,
                'queued_tasks': statuses.count('QUEUED'),
                'paused_tasks': statuses.count('PAUSED'),
            }
            for name, gauge in gauges.items():
                gauge.add_metric(labels, values[name])
            counters['results_stored'].add_metric(labels, robot.results_stored)
            counters['bad_messages'].add_metric(labels, robot.bad_messages)
        yield connection
        yield from gauges.values()
        yield from counters.values()
        fleet = self.fleet
        yield CounterMetricFamily(
            f'{PREFIX}_results_received',
            'Results delivered by the broker since the start (duplicates and bad ones too).',
            fleet.results_received,
        )
        yield CounterMetricFamily(
            f'{PREFIX}_results_stored', 'Results stored since the start.', fleet.results_stored
        )
        yield CounterMetricFamily(
            f'{PREFIX}_results_duplicate',
            'Results delivered again and not stored again.',
            fleet.duplicates,
        )
        yield GaugeMetricFamily(
            f'{PREFIX}_results_waiting',
            'Results received and not stored yet (the broker keeps them until they are).',
            fleet.results_waiting(),
        )
        yield GaugeMetricFamily(
            f'{PREFIX}_database_up',
            '1 while the fleet history stores, 0 while its database cannot be reached.',
            int(fleet.database_up),
        )


class ConsoleMetrics:
    """The metrics of one console, in a CollectorRegistry of its own."""

    def __init__(self, fleet: Fleet) -> None:
        self.registry = CollectorRegistry()
        self.tasks_ended = Counter(
            f'{PREFIX}_tasks_ended',
            'Tasks ended whose results were stored since the console started, by robot and '
            'final status.',
            [*ROBOT, 'status'],
            registry=self.registry,
        )
        self.request_counts = RequestCounts(self.registry, PREFIX, 'the console')
        self.registry.register(_FleetCollector(fleet))
        self._remove = fleet.on_change(self._on_change)

    def close(self) -> None:
        self._remove()

    def _on_change(self, change: Change) -> None:
        """On the Fleet's threads (prometheus_client's metrics are thread-safe)."""
        if change.row is None:
            return
        status = change.row['status']
        label = status if status in FINAL_STATUSES else OTHER_STATUS
        self.tasks_ended.labels(change.robot.robot_id, label).inc()
