"""Who may start what on the gateway: the role a task needs, decided by what it does.

A system task does what a route does (system/reprioritize what POST /api/tasks/reprioritize
does), so it needs that route's role wherever a request asks for it: a route that runs it, a
start that names it, a mission that has it as a step, a schedule that runs it. SYSTEM_TASK_ROLES
is the one table; every route that runs a system task takes its role from it (access.runs).
Any other task needs TASK_ROLE, and a priority of one's own PRIORITY_ROLE (it decides what is
pre-empted and overtaken, as reprioritize does): a schedule's for its runs as well.

A task_data given as JSON text (a mission step's, a schedule's) is read as the Task Manager
reads it, by the doors' reader (strict_json); what it cannot read cannot be checked, and is
refused (UnreadableTaskDataError). The nesting is bounded: objects by the body's JSON_MAX_DEPTH,
JSON text in a string by its escapes, which double at each level (20 levels fill 1 MiB).
"""

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

from task_manager.core.names import (
    CANCEL_TASK,
    CANCEL_TASK_ALIAS,
    CONFIRM,
    ENABLE_SCHEDULE,
    MISSION,
    PAUSE,
    REPRIORITIZE,
    RESUME,
    SCHEDULE,
    STOP,
    UNSCHEDULE,
    WAIT,
)
from task_manager.protocol.strict_json import RefusedJsonError, load
from task_manager_web.doors.tokens import Role

SYSTEM_TASK_ROLES: Mapping[str, Role] = MappingProxyType(
    {
        MISSION: Role.OPERATOR,
        WAIT: Role.OPERATOR,
        CONFIRM: Role.OPERATOR,
        CANCEL_TASK: Role.OPERATOR,
        CANCEL_TASK_ALIAS: Role.OPERATOR,
        STOP: Role.OPERATOR,
        PAUSE: Role.OPERATOR,
        RESUME: Role.OPERATOR,
        REPRIORITIZE: Role.ADMIN,
        SCHEDULE: Role.ADMIN,
        UNSCHEDULE: Role.ADMIN,
        ENABLE_SCHEDULE: Role.ADMIN,
    }
)
"""key: a system task, value: the role that may run it, however a request asks for it."""
TASK_ROLE = Role.OPERATOR
"""The role that may start any other task."""
PRIORITY_ROLE = Role.ADMIN
"""The role that may give a priority of its own (a start's, a schedule's runs')."""


@dataclass(frozen=True)
class Need:
    """The role a request needs, for what, and where the request asks for it."""

    role: Role
    what: str
    """`starting system/reprioritize`, `a priority of its runs`."""
    field: str
    """`task_name`, `task_data.subtasks.1.task_name`."""


class UnreadableTaskDataError(ValueError):
    """A task_data in JSON text whose effect cannot be known: it is not plain JSON."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(f'{field}: {message}')
        self.field = field


def needed_to_start(task_name: Any, task_data: Any, field: str = '') -> Need:
    """What starting `task_name` with `task_data` needs: its own role, and that of what it
    starts in turn (a mission's steps, a schedule's task and its runs' priority). `field`: where
    the request gives them, '' or a path ending in '.'."""
    name = task_name if isinstance(task_name, str) else ''
    own = Need(SYSTEM_TASK_ROLES.get(name, TASK_ROLE), f'starting {name}', f'{field}task_name')
    if name == MISSION:
        data = _document(task_data, f'{field}task_data')
        steps = data.get('subtasks') if isinstance(data, dict) else None
        return _highest(own, needed_by_steps(steps, f'{field}task_data.subtasks'))
    if name == SCHEDULE:
        data = _document(task_data, f'{field}task_data')
        if not isinstance(data, dict):
            return own
        options = data.get('options')
        gives_priority = isinstance(options, dict) and (
            'priority' in options or bool(options.get('has_priority'))
        )
        scheduled = needed_to_start(
            data.get('task_name'), data.get('task_data', ''), f'{field}task_data.'
        )
        priority_field = f'{field}task_data.options.priority'
        return _highest(own, with_runs_priority(scheduled, gives_priority, priority_field))
    return own


def needed_by_steps(steps: Any, field: str) -> Need:
    """What a mission's steps (`subtasks`, at `field`) need: the most any of them does."""
    needs = [Need(TASK_ROLE, 'starting a mission', field)]
    for index, step in enumerate(steps if isinstance(steps, list) else ()):
        if isinstance(step, dict):
            needs.append(
                needed_to_start(step.get('task_name'), step.get('task_data'), f'{field}.{index}.')
            )
    return _highest(*needs)


def with_runs_priority(scheduled: Need, gives_priority: bool, field: str) -> Need:
    """What a schedule needs besides system/schedule's own role: what starting its task or
    mission needs (`scheduled`), and PRIORITY_ROLE if its runs give a priority (at `field`)."""
    if not gives_priority:
        return scheduled
    return _highest(scheduled, Need(PRIORITY_ROLE, 'a priority of its runs', field))


def _document(task_data: Any, field: str) -> Any:
    """A task_data as the Task Manager reads it: an object as it is, JSON text parsed."""
    if not isinstance(task_data, str):
        return task_data
    try:
        return load(task_data.encode(errors='surrogatepass'))  # a lone surrogate: not UTF-8
    except RefusedJsonError as refused:
        raise UnreadableTaskDataError(field, refused.message) from None


def _highest(*needs: Need) -> Need:
    """The need of the highest role; of those, the first."""
    return max(needs, key=lambda need: need.role)
