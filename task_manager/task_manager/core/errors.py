"""The Task Manager's exceptions.

TaskManagerError
 +-- ConfigurationError      a parameters file the node cannot run with
 +-- TaskRequestError        a request that ends before its task starts (carries an ErrorCode)
 +-- InvalidTransition       a lifecycle step that the task's current status does not allow
 +-- TaskManagerUnavailable  no Task Manager answered a client in time
 +-- TaskTimeout             a client's wait for a task ran out
 +-- FellBehind              a client's iterator was read too slowly and dropped updates
"""

from task_manager.core.status import ErrorCode


class TaskManagerError(Exception):
    """Base of every error raised by the Task Manager."""


class ConfigurationError(TaskManagerError):
    """The declared tasks or node parameters are unusable; the node must not start."""


class TaskRequestError(TaskManagerError):
    """A task request fails before its task runs; `error_code` goes to the caller."""

    def __init__(self, error_code: ErrorCode, message: str) -> None:
        super().__init__(message)
        self.error_code = error_code


class InvalidTransition(TaskManagerError):  # noqa: N818 - named after the state-machine term
    """A task lifecycle transition that is not allowed from the current status."""


class TaskManagerUnavailable(TaskManagerError):  # noqa: N818 - reads as a state, like httpx's
    """No Task Manager answered within the client's timeout."""


class TaskTimeout(TaskManagerError):  # noqa: N818
    """A task did not end within the time a client was willing to wait."""


class FellBehind(TaskManagerError):  # noqa: N818 - reads as what happened, like TaskTimeout
    """An iterator of the client was read so slowly that it dropped updates (see
    bounds.UPDATES_UNREAD_MAX); what it follows should be read again."""
