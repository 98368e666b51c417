"""Task declarations: what a task is, read from the node's parameters."""

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

from task_manager.core.admission.options import OnConflict
from task_manager.core.admission.retry import NO_RETRY, RetryPolicy
from task_manager.core.bounds import SECONDS
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
    'priority': ((int,), 0),
    'on_conflict': ((str,), OnConflict.PREEMPT.value),
    'timeout_sec': ((int, float), 0.0),
    'queue_timeout_sec': ((int, float), 0.0),
    'feedback_timeout_sec': ((int, float), 0.0),
}
TIMEOUT_KEYS = ('timeout_sec', 'queue_timeout_sec', 'feedback_timeout_sec')
# Optional keys that hold several values, each checked by its own parser.
COMPOUND_KEYS = ('resources', 'retry')
# Keys whose value is a map: ROS parameters give it flat (`retry.max_attempts`).
MAP_KEYS = ('retry',)
# key: number in a task entry's `retry` map, value: accepted Python types
RETRY_NUMBER_TYPES: dict[str, tuple[type, ...]] = {
    'max_attempts': (int,),
    'initial_delay_sec': (int, float),
    'multiplier': (int, float),
    'max_delay_sec': (int, float),
}
RETRY_KEYS = (*RETRY_NUMBER_TYPES, 'on_error_codes')
RESERVED_RESOURCE_PREFIX = '@'
"""Starts the implicit resources (core/admission/claims.py), which no declaration may name."""
_RESOURCE_PATTERN = re.compile(r'[A-Za-z0-9_./-]+')
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
    if problem := SECONDS.problem(f'{key}.cancel_timeout', options['cancel_timeout']):
        raise ConfigurationError(f'{label}: {problem}')
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
        resources=_resources(f'{label}: {key}.resources', entry.get('resources')),
        priority=options['priority'],
        on_conflict=_on_conflict(f'{label}: {key}.on_conflict', options['on_conflict']),
        **_timeouts(label, key, options, interface),
        retry=_retry_policy(f'{label}: {key}.retry', entry.get('retry')),
        parameter_key=key,
    )


def _resources(what: str, value: Any) -> tuple[str, ...]:
    """The declared resources, sorted; none when the key is left out."""
    if value is None:
        return ()
    value = _strings(what, value, 'e.g. [base]')
    for name in value:
        if name.startswith(RESERVED_RESOURCE_PREFIX):
            raise ConfigurationError(
                f'{what}: {name!r} starts with {RESERVED_RESOURCE_PREFIX!r}, which is reserved '
                "for the implicit resources (blocking, a task's one goal slot)"
            )
        if not _RESOURCE_PATTERN.fullmatch(name):
            raise ConfigurationError(
                f'{what}: {name!r} is not a resource name (one or more letters, digits and _ . / -)'
            )
    twice = sorted({name for name in value if value.count(name) > 1})
    if twice:
        raise ConfigurationError(f'{what} names {", ".join(map(repr, twice))} more than once')
    return tuple(sorted(value))


def _strings(what: str, value: Any, example: str) -> list[str]:
    """`value` if it is a list of strings; else ConfigurationError saying `what` is wrong."""
    if not isinstance(value, list | tuple) or not all(isinstance(item, str) for item in value):
        raise ConfigurationError(f'{what} must be a list of strings, {example}, got {value!r}')
    return list(value)


def _on_conflict(what: str, text: str) -> OnConflict:
    try:
        return OnConflict(text.strip().lower())
    except ValueError:
        allowed = ', '.join(choice.value for choice in OnConflict)
        raise ConfigurationError(f'{what} must be one of {allowed}, got {text!r}') from None


def _timeouts(
    label: str, key: str, options: Mapping[str, Any], interface: InterfaceName
) -> dict[str, float]:
    """The entry's timeouts as floats (0: none); a feedback timeout only for an action."""
    for name in TIMEOUT_KEYS:
        if problem := SECONDS.problem(f'{key}.{name}', options[name]):
            raise ConfigurationError(f'{label}: {problem} (0: none)')
    if options['feedback_timeout_sec'] and interface.kind is not TaskKind.ACTION:
        raise ConfigurationError(
            f'{label}: feedback_timeout_sec is only for action tasks (a service sends no '
            f'feedback), and {interface} is a service'
        )
    return {name: float(options[name]) for name in TIMEOUT_KEYS}


def _retry_policy(what: str, value: Any) -> RetryPolicy:
    """The entry's `retry` map as a RetryPolicy; no retry when the key is left out."""
    if value is None:
        return NO_RETRY
    if not isinstance(value, Mapping):
        raise ConfigurationError(f'{what} must be a map of {", ".join(RETRY_KEYS)}, got {value!r}')
    unknown = sorted(str(name) for name in value if name not in RETRY_KEYS)
    if unknown:
        raise ConfigurationError(
            f'{what}.{unknown[0]} is not a key of retry; its keys are {", ".join(RETRY_KEYS)}'
        )
    if 'max_attempts' not in value:
        raise ConfigurationError(f'{what}.max_attempts is missing (the attempts in all, >= 1)')
    values = {
        name: checked_value(f'{what}.{name}', value[name], types)
        for name, types in RETRY_NUMBER_TYPES.items()
        if name in value
    }
    codes = _strings(f'{what}.on_error_codes', value.get('on_error_codes', ()), 'e.g. [aborted]')
    policy = RetryPolicy(
        max_attempts=values['max_attempts'],
        initial_delay_sec=float(values.get('initial_delay_sec', NO_RETRY.initial_delay_sec)),
        multiplier=float(values.get('multiplier', NO_RETRY.multiplier)),
        max_delay_sec=float(values.get('max_delay_sec', NO_RETRY.max_delay_sec)),
        on_error_codes=tuple(code.strip().lower() for code in codes),
    )
    problem = policy.problem()
    if problem:
        raise ConfigurationError(f'{what}.{problem}')
    return policy


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


def nested_entry(flat: Mapping[str, Any]) -> dict[str, Any]:
    """A task entry as ROS parameters give it, with each map of MAP_KEYS gathered again:
    `{'retry.max_attempts': 3}` becomes `{'retry': {'max_attempts': 3}}`."""
    entry: dict[str, Any] = {}
    maps: dict[str, dict[str, Any]] = {}
    for name, value in flat.items():
        head, dot, rest = name.partition('.')
        if dot and head in MAP_KEYS:
            maps.setdefault(head, {})[rest] = value
        else:
            entry[name] = value
    for head, inner in maps.items():
        entry.setdefault(head, inner)  # `retry: 3` beside `retry.x` stays 3, refused as no map
    return entry


def unknown_keys(entry: Mapping[str, Any]) -> list[str]:
    """Keys of a task entry that the Task Manager does not know (likely typos); those inside
    a map as `retry.<key>`, whether the map is nested or flat."""
    known = {*REQUIRED_KEYS, *OPTIONAL_KEYS, *COMPOUND_KEYS}
    unknown: set[str] = set()
    for name, value in entry.items():
        head, dot, rest = name.partition('.')
        if name == 'retry' and isinstance(value, Mapping):
            unknown.update(f'retry.{inner}' for inner in value if inner not in RETRY_KEYS)
        elif dot and head == 'retry':
            if rest not in RETRY_KEYS:
                unknown.add(name)
        elif name not in known:
            unknown.add(name)
    return sorted(unknown)


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
