"""Task declarations: what a task is, read from the node's parameters."""

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

from task_manager.core.admission.options import OnConflict
from task_manager.core.admission.retry import NO_RETRY, RetryPolicy
from task_manager.core.errors import ConfigurationError

DEFAULT_CANCEL_TIMEOUT_SEC = 5.0
REQUIRED_KEYS = ('task_name', 'topic', 'msg_interface')
# key: optional parameter of a task entry, value: (accepted Python types, default)
OPTIONAL_KEYS: dict[str, tuple[tuple[type, ...], Any]] = {
    'blocking': ((bool,), False),
    'cancel_on_stop': ((bool,), False),
    'reentrant': ((bool,), False),
    'cancel_reported_as_success': ((bool,), False),
    'service_success_field': ((str,), ''),
    'cancel_timeout': ((int, float), DEFAULT_CANCEL_TIMEOUT_SEC),
    'pause': ((str,), 'none'),
}
_INTERFACE_PATTERN = re.compile(r'^(?P<package>\w+)[./](?P<kind>action|srv)[./](?P<name>\w+)$')


class TaskKind(StrEnum):
    """What implements a task."""

    ACTION = 'action'
    SERVICE = 'srv'
    SYSTEM = 'system'
    """Built into the Task Manager (system/mission, system/wait, ...)."""


class PauseMode(StrEnum):
    """How a task pauses (system/pause) and resumes (system/resume)."""

    NONE = 'none'
    """It cannot be paused (the default): a pause request for it fails, saying so."""
    RESTART = 'restart'
    """Its goal is cancelled on pause and the same goal is sent again on resume (actions)."""
    BETWEEN_SUBTASKS = 'between_subtasks'
    """system/mission only: the running subtask goes on, the next waits for the resume."""


# The pause modes a task entry may declare.
DECLARABLE_PAUSE_MODES = (PauseMode.NONE, PauseMode.RESTART)


@dataclass(frozen=True)
class InterfaceName:
    """A ROS interface type name, e.g. `test_msgs/action/Fibonacci`."""

    package: str
    kind: TaskKind
    name: str

    def __str__(self) -> str:
        return f'{self.package}/{self.kind}/{self.name}'


@dataclass(frozen=True)
class TaskSpec:
    """One declared task type and its properties."""

    task_name: str
    topic: str
    interface: InterfaceName
    blocking: bool = False
    cancel_on_stop: bool = False
    reentrant: bool = False
    cancel_reported_as_success: bool = False
    service_success_field: str = ''
    cancel_timeout_sec: float = DEFAULT_CANCEL_TIMEOUT_SEC
    pause: PauseMode = PauseMode.NONE
    resources: tuple[str, ...] = ()
    """What it holds while it runs (besides the implicit slots of blocking and reentrant)."""
    priority: int = 0
    on_conflict: OnConflict = OnConflict.PREEMPT
    timeout_sec: float = 0.0
    """From start to end; 0: none."""
    queue_timeout_sec: float = 0.0
    """The longest wait in the queue; 0: none."""
    feedback_timeout_sec: float = 0.0
    """The longest an action may go without feedback; 0: none."""
    retry: RetryPolicy = NO_RETRY
    parameter_key: str = field(default='', compare=False)

    @property
    def kind(self) -> TaskKind:
        return self.interface.kind


def checked_value(what: str, value: Any, types: tuple[type, ...]) -> Any:
    """Return `value` if it is one of `types`; else ConfigurationError saying `what` is wrong.

    bool is an int in Python, but `cancel_timeout: true` is surely a mistake: a bool only
    passes where bool is among `types`.
    """
    if not isinstance(value, types) or (bool not in types and isinstance(value, bool)):
        expected = ' or '.join(t.__name__ for t in types)
        raise ConfigurationError(f'{what} must be {expected}, got {value!r}')
    return value


def parse_interface_name(text: str) -> InterfaceName:
    """Parse `pkg.action.Name`, `pkg/action/Name`, `pkg.srv.Name` or `pkg/srv/Name`."""
    match = _INTERFACE_PATTERN.match(text.strip())
    if match is None:
        raise ConfigurationError(
            f'msg_interface {text!r} is not of the form package.action.Name, '
            'package.srv.Name, package/action/Name or package/srv/Name'
        )
    return InterfaceName(match['package'], TaskKind(match['kind']), match['name'])


def parse_task_spec(key: str, entry: Mapping[str, Any]) -> TaskSpec:
    """Build the TaskSpec of parameter entry `key`; raise ConfigurationError naming the task."""
    label = f"task '{entry.get('task_name') or key}'"
    for required in REQUIRED_KEYS:
        value = entry.get(required)
        if not isinstance(value, str) or not value.strip():
            problem = (
                'is missing' if value is None else f'must be a non-empty string, got {value!r}'
            )
            raise ConfigurationError(f'{label}: {key}.{required} {problem}')
    options = {
        name: checked_value(f'{label}: {key}.{name}', entry.get(name, default), types)
        for name, (types, default) in OPTIONAL_KEYS.items()
    }
    try:
        interface = parse_interface_name(entry['msg_interface'])
    except ConfigurationError as error:
        raise ConfigurationError(f'{label}: {error}') from error
    if not options['cancel_timeout'] >= 0:  # also rejects NaN
        raise ConfigurationError(f'{label}: {key}.cancel_timeout must be >= 0')
    pause = _pause_mode(label, key, options['pause'], interface)
    if pause is PauseMode.RESTART and options['cancel_reported_as_success']:
        raise ConfigurationError(
            f'{label}: pause: restart cancels the goal to pause it, which '
            'cancel_reported_as_success would report as the task succeeding; use one of them'
        )
    if options['service_success_field'] and interface.kind is not TaskKind.SERVICE:
        raise ConfigurationError(
            f'{label}: service_success_field is only for service tasks, '
            f'and {interface} is an action'
        )
    return TaskSpec(
        task_name=entry['task_name'].strip(),
        topic=entry['topic'].strip(),
        interface=interface,
        blocking=options['blocking'],
        cancel_on_stop=options['cancel_on_stop'],
        reentrant=options['reentrant'],
        cancel_reported_as_success=options['cancel_reported_as_success'],
        service_success_field=options['service_success_field'],
        cancel_timeout_sec=float(options['cancel_timeout']),
        pause=pause,
        parameter_key=key,
    )


def _pause_mode(label: str, key: str, text: str, interface: InterfaceName) -> PauseMode:
    """The entry's `pause`: none or restart, and restart only for actions (a service call
    cannot be interrupted, so it cannot be paused by cancelling it)."""
    allowed = ', '.join(mode.value for mode in DECLARABLE_PAUSE_MODES)
    try:
        mode = PauseMode(text.strip().lower())
    except ValueError:
        mode = None
    if mode not in DECLARABLE_PAUSE_MODES:
        raise ConfigurationError(f'{label}: {key}.pause must be one of {allowed}, got {text!r}')
    if mode is PauseMode.RESTART and interface.kind is not TaskKind.ACTION:
        raise ConfigurationError(
            f'{label}: pause: restart is only for action tasks (a service call cannot be '
            f'cancelled and sent again), and {interface} is a service'
        )
    assert mode is not None
    return mode


def unknown_keys(entry: Mapping[str, Any]) -> list[str]:
    """Keys of a task entry that the Task Manager does not know (likely typos)."""
    return sorted(set(entry) - set(REQUIRED_KEYS) - set(OPTIONAL_KEYS))


def parse_task_specs(
    task_keys: Any, entries: Mapping[str, Mapping[str, Any]], reserved_names: set[str]
) -> list[TaskSpec]:
    """Parse every entry listed in `tasks`; reject duplicates and reserved (system) names."""
    if not isinstance(task_keys, list | tuple) or not all(isinstance(k, str) for k in task_keys):
        raise ConfigurationError(f"parameter 'tasks' must be a list of strings, got {task_keys!r}")
    specs: list[TaskSpec] = []
    keys_by_name: dict[str, str] = {}
    for key in task_keys:
        if key not in entries:
            raise ConfigurationError(
                f"task '{key}': listed in 'tasks' but has no parameters "
                f'({key}.task_name, {key}.topic, {key}.msg_interface)'
            )
        spec = parse_task_spec(key, entries[key])
        if spec.task_name in reserved_names:
            raise ConfigurationError(
                f"task '{spec.task_name}': the name is reserved for a system task"
            )
        if spec.task_name in keys_by_name:
            raise ConfigurationError(
                f"task '{spec.task_name}': declared twice "
                f'(entries {keys_by_name[spec.task_name]!r} and {key!r})'
            )
        keys_by_name[spec.task_name] = key
        specs.append(spec)
    return specs
