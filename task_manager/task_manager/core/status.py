"""Task statuses and error codes, with the same string values as the ROS interfaces."""

from enum import StrEnum


class TaskStatus(StrEnum):
    """Where a task is in its lifecycle."""

    RECEIVED = 'RECEIVED'
    """Accepted by the manager, not started on its server yet (e.g. waiting for conflicts)."""
    IN_PROGRESS = 'IN_PROGRESS'
    """Running on its server."""
    PAUSED = 'PAUSED'
    """Started, then paused by system/pause; still active (not in the original package)."""
    DONE = 'DONE'
    """Ended successfully (or cancelled, for tasks with cancel_reported_as_success)."""
    ERROR = 'ERROR'
    """Ended in failure, or never started; the error code says why when the manager knows."""
    CANCELED = 'CANCELED'
    """Ended by a cancel: its client, a conflicting task, system/cancel_task or system/stop."""

    @property
    def is_final(self) -> bool:
        return self in (TaskStatus.DONE, TaskStatus.ERROR, TaskStatus.CANCELED)

    @property
    def is_started(self) -> bool:
        """Started and not ended: shown in active_tasks."""
        return self in (TaskStatus.IN_PROGRESS, TaskStatus.PAUSED)


class ErrorCode(StrEnum):
    """Why the manager failed a request (ExecuteTask result constants); empty when none."""

    NONE = ''
    DUPLICATE_TASK_ID = 'duplicate_id'
    TASK_DATA_PARSING_FAILED = 'task_data_parsing_failed'
    TASK_START_FAILED = 'task_start_failed'
    TASK_CANCEL_FAILED = 'task_cancel_failed'
    UNKNOWN_TASK = 'unknown_task'
    INVALID_REQUEST = 'invalid_request'
    """An id, task name or source with refused characters or too long (request_text.py)."""


class ServerOutcome(StrEnum):
    """How the server behind a task ended it (GoalStatus is mapped to this in ros/)."""

    SUCCEEDED = 'SUCCEEDED'
    CANCELED = 'CANCELED'
    ABORTED = 'ABORTED'


class CancelReason(StrEnum):
    """Who asked for a task to be cancelled."""

    CLIENT = 'client'
    """The client that started the task cancelled its own request."""
    CONFLICT = 'conflict'
    """A newer blocking task, or a newer goal of the same non-reentrant task."""
    CANCEL_TASK = 'cancel_task'
    """system/cancel_task named the task's id."""
    STOP = 'stop'
    """system/stop."""
    MISSION = 'mission'
    """The mission the task belongs to was cancelled."""
    SCHEDULE = 'schedule'
    """A newer run of the same schedule replaced it (overlap CANCEL_OTHER)."""
    SHUTDOWN = 'shutdown'
    """The Task Manager is shutting down."""
