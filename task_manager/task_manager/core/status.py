"""Task statuses and error codes, with the same string values as the ROS interfaces."""

from enum import StrEnum


class TaskStatus(StrEnum):
    """Where a task is in its lifecycle."""

    RECEIVED = 'RECEIVED'
    """Accepted by the manager, not started on its server yet (e.g. waiting for conflicts)."""
    QUEUED = 'QUEUED'
    """Waiting for its resources (on_conflict: queue); still active (not in the original)."""
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
    def is_listed(self) -> bool:
        """Shown in active_tasks: started and not ended, or waiting in the queue."""
        return self in (TaskStatus.QUEUED, TaskStatus.IN_PROGRESS, TaskStatus.PAUSED)

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
    PREEMPTION_REFUSED = 'preemption_refused'
    """Its resources are held by a task of higher priority, which goes on."""
    RESOURCE_BUSY = 'resource_busy'
    """Its resources are held and it asked not to wait (on_conflict: reject)."""
    QUEUE_FULL = 'queue_full'
    """It would have waited, but the queue holds max_queued tasks already."""
    TIMEOUT = 'timeout'
    """One of its timeouts fired (timeout_sec, queue_timeout_sec, feedback_timeout_sec), or
    nobody answered a system/confirm within its own timeout_sec."""
    REJECTED = 'rejected'
    """An operator rejected a system/confirm."""


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
    """Pre-empted: a newer task of at least its priority needs one of its resources."""
    TIMEOUT = 'timeout'
    """One of its timeouts fired."""
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
