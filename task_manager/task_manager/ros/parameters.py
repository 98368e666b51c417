"""Reading the node's parameters into task declarations and settings."""

from dataclasses import dataclass
from typing import Any

from rclpy.node import Node

from task_manager.core.admission.arbiter import DEFAULT_MAX_QUEUED
from task_manager.core.admission.priority import parse_source_priorities
from task_manager.core.bounds import HISTORY_BYTES_DEFAULT
from task_manager.core.errors import ConfigurationError
from task_manager.core.history import location as history_location
from task_manager.core.history.store import HistoryInUseError
from task_manager.core.task_spec import (
    TaskSpec,
    checked_value,
    nested_entry,
    parse_task_specs,
    unknown_keys,
)
from task_manager.middleware_watchdog import LONGEST_TIMEOUT_SEC, SHORTEST_TIMEOUT_SEC
from task_manager.rclpy_tools.log import NodeLog
from task_manager.ros.running.execution import RunnerTimeouts

# key: node-level parameter, value: (accepted types, default)
NODE_PARAMETERS: dict[str, tuple[tuple[type, ...], Any]] = {
    'enable_task_servers': ((bool,), False),
    'server_wait_timeout': ((int, float), RunnerTimeouts.server_wait_sec),
    'goal_response_timeout': ((int, float), RunnerTimeouts.goal_response_sec),
    'results_history_size': ((int,), 1000),
    'service_response_timeout': ((int, float), RunnerTimeouts.service_response_sec),
    'server_check_period': ((int, float), RunnerTimeouts.server_check_period_sec),
    'server_loss_timeout': ((int, float), RunnerTimeouts.server_loss_timeout_sec),
    'instance_check_timeout': ((int, float), 0.3),
    'middleware_watchdog_timeout': ((int, float), 30.0),
    'publish_task_events': ((bool,), True),
    'feedback_rate_hz': ((int, float), 10.0),
    # None: the default file under ROS_HOME (see default_history_path)
    'history_path': ((str,), None),
    'history_max_results': ((int,), 1_000_000),
    'history_max_age_days': ((int, float), 90.0),
    'history_max_bytes': ((int,), HISTORY_BYTES_DEFAULT),
    'max_queued': ((int,), DEFAULT_MAX_QUEUED),
}
SOURCE_PRIORITIES = 'source_priorities'
"""The map of priorities by source; ROS gives it flat: `source_priorities.joystick`."""


POSITIVE_PARAMETERS = (
    'server_wait_timeout',
    'goal_response_timeout',
    'service_response_timeout',
    'server_check_period',
    'server_loss_timeout',
    'feedback_rate_hz',
)


@dataclass(frozen=True)
class NodeSettings:
    """Node-level parameters."""

    enable_task_servers: bool
    timeouts: RunnerTimeouts
    results_history_size: int
    instance_check_timeout_sec: float
    middleware_watchdog_timeout_sec: float
    """How long the DDS timer thread may not run before the node exits (0: not watched)."""
    publish_task_events: bool
    feedback_rate_hz: float
    history_path: str
    """The SQLite file of the task history; '' keeps it in memory only."""
    history_max_results: int
    history_max_age_days: float
    history_max_bytes: int
    """The bytes of ended tasks the history keeps (their rows' size); 0: no limit."""
    max_queued: int
    """The most tasks waiting in the queue."""
    source_priorities: dict[str, int]
    """key: source (or its part before ':'), value: the priority it adds to a request's."""


def default_history_path(node: Node) -> str:
    """The node's own history file under ROS_HOME (see history_location); the one file of
    the versions before is moved there first if the node has none yet."""
    home = history_location.ros_home()
    path = history_location.default_history_path(
        home, node.context.get_domain_id(), node.get_fully_qualified_name()
    )
    legacy = history_location.legacy_history_path(home)
    try:
        if history_location.adopt_legacy_history(legacy, path):
            NodeLog.of(node).info(
                f'moved the task history of an earlier version from {legacy} to {path}: '
                'each ROS domain and node has its own history file now'
            )
    except HistoryInUseError as error:
        NodeLog.of(node).warning(f'left the task history {legacy} where it is: {error}')
    except OSError as error:
        raise ConfigurationError(
            f'cannot move the task history {legacy} to {path}: {error}'
        ) from None
    return path


def read_settings(node: Node) -> NodeSettings:
    values = {
        name: checked_value(
            f'parameter {name!r}',
            node.get_parameter(name).value if node.has_parameter(name) else default,
            types,
        )
        for name, (types, default) in NODE_PARAMETERS.items()
        if default is not None or node.has_parameter(name)
    }
    if values['results_history_size'] < 0:
        raise ConfigurationError("parameter 'results_history_size' must be >= 0")
    for name in ('history_max_results', 'history_max_age_days', 'history_max_bytes'):
        if values[name] < 0:
            raise ConfigurationError(f'parameter {name!r} must be >= 0 (0: no limit)')
    if values['max_queued'] < 0:
        raise ConfigurationError(f"parameter 'max_queued' must be >= 0, got {values['max_queued']}")
    if values['instance_check_timeout'] < 0:
        raise ConfigurationError("parameter 'instance_check_timeout' must be >= 0")
    watchdog_timeout = values['middleware_watchdog_timeout']
    if (
        watchdog_timeout != 0
        and not SHORTEST_TIMEOUT_SEC <= watchdog_timeout <= LONGEST_TIMEOUT_SEC
    ):
        raise ConfigurationError(
            "parameter 'middleware_watchdog_timeout' must be 0 (off) or from "
            f'{SHORTEST_TIMEOUT_SEC:g} to {LONGEST_TIMEOUT_SEC:g} s, got {watchdog_timeout!r}'
        )
    for name in POSITIVE_PARAMETERS:
        if not values[name] > 0:
            raise ConfigurationError(f'parameter {name!r} must be > 0, got {values[name]!r}')
    return NodeSettings(
        enable_task_servers=values['enable_task_servers'],
        results_history_size=values['results_history_size'],
        instance_check_timeout_sec=float(values['instance_check_timeout']),
        middleware_watchdog_timeout_sec=float(values['middleware_watchdog_timeout']),
        publish_task_events=values['publish_task_events'],
        feedback_rate_hz=float(values['feedback_rate_hz']),
        history_path=(
            values['history_path'] if 'history_path' in values else default_history_path(node)
        ),
        history_max_results=values['history_max_results'],
        history_max_age_days=float(values['history_max_age_days']),
        history_max_bytes=values['history_max_bytes'],
        max_queued=values['max_queued'],
        source_priorities=read_source_priorities(node),
        timeouts=RunnerTimeouts(
            server_wait_sec=float(values['server_wait_timeout']),
            goal_response_sec=float(values['goal_response_timeout']),
            service_response_sec=float(values['service_response_timeout']),
            server_check_period_sec=float(values['server_check_period']),
            server_loss_timeout_sec=float(values['server_loss_timeout']),
        ),
    )


def read_source_priorities(node: Node) -> dict[str, int]:
    """The `source_priorities.<source>` parameters, as a map of source to priority."""
    if node.has_parameter(SOURCE_PRIORITIES):
        raise ConfigurationError(
            f"parameter '{SOURCE_PRIORITIES}' must be a map of source to priority, e.g. "
            f'{{joystick: 100, CLOUD: 10}}, got {node.get_parameter(SOURCE_PRIORITIES).value!r}'
        )
    prefixed = node.get_parameters_by_prefix(SOURCE_PRIORITIES)
    return parse_source_priorities({name: parameter.value for name, parameter in prefixed.items()})


def read_task_specs(node: Node, reserved_names: set[str]) -> list[TaskSpec]:
    """Parse `tasks` and every `<key>.*` entry; warn about keys nobody reads."""
    if not node.has_parameter('tasks'):
        raise ConfigurationError(
            "parameter 'tasks' is missing: list the keys of the task entries, "
            'e.g. tasks: [navigate]'
        )
    task_keys = node.get_parameter('tasks').value
    if task_keys is None:
        task_keys = []
    entries = {}
    for key in task_keys if isinstance(task_keys, list | tuple) else []:
        prefixed = node.get_parameters_by_prefix(key) if isinstance(key, str) else {}
        entries[key] = nested_entry({name: parameter.value for name, parameter in prefixed.items()})
    specs = parse_task_specs(task_keys, entries, reserved_names)
    for spec in specs:
        for unknown in unknown_keys(entries[spec.parameter_key]):
            NodeLog.of(node).warning(
                f"task '{spec.task_name}': ignoring unknown parameter "
                f'{spec.parameter_key}.{unknown}'
            )
    return specs
