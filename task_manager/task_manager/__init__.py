"""ROS 2 Task Manager: start, track and end every task of a robot in one place.

The public API is what `__all__` lists; it is imported lazily so that the ROS-free core
(`task_manager.core`) can be used without loading rclpy.
"""

import importlib
from typing import Any

__all__ = [
    'ActiveTaskInfo',
    'ConfirmAnswer',
    'Decision',
    'ErrorCode',
    'EventsLost',
    'OnConflict',
    'OverlapPolicy',
    'Pause',
    'ScheduleInfo',
    'Subtask',
    'TaskEvent',
    'TaskEventKind',
    'TaskHandle',
    'TaskManagerClient',
    'TaskManagerError',
    'TaskManagerUnavailable',
    'TaskResult',
    'TaskState',
    'TaskStats',
    'TaskStatus',
    'TaskTimeout',
    'scheduled_next_run',
]

# key: public name, value: the module that defines it
_DEFINED_IN = {
    'ActiveTaskInfo': 'task_manager.client.records',
    'ConfirmAnswer': 'task_manager.client.interventions',
    'Decision': 'task_manager.client.records',
    'EventsLost': 'task_manager.client.records',
    'OnConflict': 'task_manager.core.admission.options',
    'Subtask': 'task_manager.client.missions',
    'Pause': 'task_manager.client.records',
    'ScheduleInfo': 'task_manager.client.schedules',
    'scheduled_next_run': 'task_manager.client.schedules',
    'OverlapPolicy': 'task_manager.core.schedules.schedule',
    'TaskHandle': 'task_manager.client.handle',
    'TaskManagerClient': 'task_manager.client.task_manager_client',
    'TaskResult': 'task_manager.client.records',
    'TaskState': 'task_manager.client.records',
    'TaskEvent': 'task_manager.client.records',
    'TaskEventKind': 'task_manager.client.records',
    'TaskStats': 'task_manager.core.history.stats',
    'ErrorCode': 'task_manager.core.status',
    'TaskStatus': 'task_manager.core.status',
    'TaskManagerError': 'task_manager.core.errors',
    'TaskManagerUnavailable': 'task_manager.core.errors',
    'TaskTimeout': 'task_manager.core.errors',
}


def __getattr__(name: str) -> Any:
    if name not in _DEFINED_IN:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    return getattr(importlib.import_module(_DEFINED_IN[name]), name)


def __dir__() -> list[str]:
    return sorted(__all__)
