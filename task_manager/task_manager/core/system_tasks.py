"""Declarations of the system tasks (fixed; not configurable from the parameters file)."""

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
from task_manager.core.task_spec import InterfaceName, PauseMode, TaskKind, TaskSpec


def _system_spec(name: str, kind: TaskKind, interface: str, **properties: Any) -> TaskSpec:
    return TaskSpec(
        task_name=name,
        topic='',
        interface=InterfaceName('task_manager_msgs', kind, interface),
        **properties,
    )


MISSION_SPEC = _system_spec(
    MISSION, TaskKind.ACTION, 'Mission', cancel_on_stop=True, pause=PauseMode.BETWEEN_SUBTASKS
)
# Several cancels or stops may run at once; `success: false` makes their status ERROR.
CANCEL_TASK_SPEC = _system_spec(
    CANCEL_TASK, TaskKind.SERVICE, 'CancelTasks', reentrant=True, service_success_field='success'
)
CANCEL_TASK_ALIAS_SPEC = _system_spec(
    CANCEL_TASK_ALIAS,
    TaskKind.SERVICE,
    'CancelTasks',
    reentrant=True,
    service_success_field='success',
)
STOP_SPEC = _system_spec(
    STOP, TaskKind.SERVICE, 'StopTasks', reentrant=True, service_success_field='success'
)
WAIT_SPEC = _system_spec(WAIT, TaskKind.ACTION, 'Wait', blocking=True, cancel_on_stop=True)
PAUSE_SPEC = _system_spec(
    PAUSE, TaskKind.SERVICE, 'PauseTasks', reentrant=True, service_success_field='success'
)
RESUME_SPEC = _system_spec(
    RESUME, TaskKind.SERVICE, 'ResumeTasks', reentrant=True, service_success_field='success'
)
REPRIORITIZE_SPEC = _system_spec(
    REPRIORITIZE,
    TaskKind.SERVICE,
    'ReprioritizeTasks',
    reentrant=True,
    service_success_field='success',
)
SCHEDULE_SPEC = _system_spec(
    SCHEDULE, TaskKind.SERVICE, 'ScheduleTask', reentrant=True, service_success_field='success'
)
UNSCHEDULE_SPEC = _system_spec(
    UNSCHEDULE, TaskKind.SERVICE, 'Unschedule', reentrant=True, service_success_field='success'
)
ENABLE_SCHEDULE_SPEC = _system_spec(
    ENABLE_SCHEDULE,
    TaskKind.SERVICE,
    'EnableSchedules',
    reentrant=True,
    service_success_field='success',
)
# Several confirmations may wait at once; stop cancels them, as it cancels a mission.
CONFIRM_SPEC = _system_spec(
    CONFIRM, TaskKind.ACTION, 'Confirm', reentrant=True, cancel_on_stop=True
)

SYSTEM_SPECS = (
    MISSION_SPEC,
    CANCEL_TASK_SPEC,
    CANCEL_TASK_ALIAS_SPEC,
    STOP_SPEC,
    WAIT_SPEC,
    PAUSE_SPEC,
    RESUME_SPEC,
    REPRIORITIZE_SPEC,
    SCHEDULE_SPEC,
    UNSCHEDULE_SPEC,
    ENABLE_SCHEDULE_SPEC,
    CONFIRM_SPEC,
)
