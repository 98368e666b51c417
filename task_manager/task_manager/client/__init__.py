"""The Python client of the Task Manager: `TaskManagerClient` and what it returns.

One module per concern, composed by `TaskManagerClient` (task_manager_client.py): the
connection (connection.py), the tasks it starts (tasks.py, handle.py), watching (watching.py,
listeners.py), what the Task Manager keeps (history.py, parameters.py), pauses and answers to
confirmations (interventions.py), schedules (schedules.py), missions (missions.py), the
records (records.py) and message fields as Python values (message_values.py).
"""

from task_manager.client.connection import DEFAULT_TIMEOUT_SEC
from task_manager.client.handle import FeedbackCallback, TaskHandle
from task_manager.client.history import FINAL_STATUSES
from task_manager.client.interventions import ConfirmAnswer
from task_manager.client.missions import Subtask
from task_manager.client.records import (
    ActiveTaskInfo,
    Decision,
    EventsLost,
    Pause,
    TaskEvent,
    TaskEventKind,
    TaskResult,
    TaskState,
)
from task_manager.client.schedules import ScheduleInfo, When, scheduled_next_run
from task_manager.client.task_manager_client import TaskManagerClient

__all__ = [
    'DEFAULT_TIMEOUT_SEC',
    'FINAL_STATUSES',
    'ActiveTaskInfo',
    'ConfirmAnswer',
    'Decision',
    'EventsLost',
    'FeedbackCallback',
    'Pause',
    'ScheduleInfo',
    'Subtask',
    'TaskEvent',
    'TaskEventKind',
    'TaskHandle',
    'TaskManagerClient',
    'TaskResult',
    'TaskState',
    'When',
    'scheduled_next_run',
]
