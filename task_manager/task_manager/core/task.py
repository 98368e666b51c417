"""One task request and its lifecycle: RECEIVED -> IN_PROGRESS -> DONE | ERROR | CANCELED."""

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from task_manager.core.errors import InvalidTransition
from task_manager.core.status import CancelReason, ErrorCode, ServerOutcome, TaskStatus
from task_manager.core.task_spec import TaskSpec

# key: status, value: the statuses a task may move to from it
_ALLOWED_TRANSITIONS: dict[TaskStatus, frozenset[TaskStatus]] = {
    TaskStatus.RECEIVED: frozenset({TaskStatus.IN_PROGRESS, TaskStatus.ERROR, TaskStatus.CANCELED}),
    TaskStatus.IN_PROGRESS: frozenset({TaskStatus.DONE, TaskStatus.ERROR, TaskStatus.CANCELED}),
    TaskStatus.DONE: frozenset(),
    TaskStatus.ERROR: frozenset(),
    TaskStatus.CANCELED: frozenset(),
}


@dataclass(frozen=True)
class TaskRequest:
    """A request to run a task, as a client sends it."""

    task_id: str
    task_name: str
    source: str
    task_data: str
    parent_id: str = ''
    """The mission this task is a subtask of, if any."""


@dataclass(frozen=True)
class TaskEnd:
    """How a task ended: status, result message as a dict, and error code."""

    status: TaskStatus
    result: dict[str, Any] = field(default_factory=dict)
    error_code: ErrorCode = ErrorCode.NONE


@dataclass
class TaskRecord:
    """Everything the manager knows of one task request, from receipt to its end."""

    task_id: str
    spec: TaskSpec
    source: str
    status: TaskStatus = TaskStatus.RECEIVED
    error_code: ErrorCode = ErrorCode.NONE
    result: dict[str, Any] = field(default_factory=dict)
    received_at: float = field(default_factory=time.time)
    started_at: float | None = None
    ended_at: float | None = None
    latest_feedback: dict[str, Any] | None = None
    feedback_at: float | None = None
    cancel_reason: CancelReason | None = None
    parent_id: str = ''
    """The mission this task runs in, if any."""
    task_data: str = ''
    """The request's task_data, as the client sent it."""
    sequence: int | None = None
    """Once ended: its number in the task history (it only grows)."""
    feedback_listeners: list[Callable[['TaskRecord'], None]] = field(
        default_factory=list, repr=False
    )
    """Called on every new feedback (the event stream; a task server's client)."""

    @property
    def task_name(self) -> str:
        return self.spec.task_name

    @property
    def is_final(self) -> bool:
        return self.status.is_final

    def _move_to(self, status: TaskStatus) -> None:
        if status not in _ALLOWED_TRANSITIONS[self.status]:
            raise InvalidTransition(
                f'task {self.task_id}: cannot go from {self.status} to {status}'
            )
        self.status = status

    def mark_started(self, now: float | None = None) -> None:
        self._move_to(TaskStatus.IN_PROGRESS)
        self.started_at = time.time() if now is None else now

    def mark_ended(
        self,
        status: TaskStatus,
        result: dict[str, Any] | None = None,
        error_code: ErrorCode = ErrorCode.NONE,
        now: float | None = None,
    ) -> None:
        if not status.is_final:
            raise InvalidTransition(f'task {self.task_id}: {status} is not an end status')
        self._move_to(status)
        self.result = result if result is not None else {}
        self.error_code = error_code
        self.ended_at = time.time() if now is None else now

    def record_feedback(self, feedback: dict[str, Any], now: float | None = None) -> None:
        self.latest_feedback = feedback
        self.feedback_at = time.time() if now is None else now
        for listener in self.feedback_listeners:
            listener(self)

    def request_cancel(self, reason: CancelReason) -> None:
        """Remember the first reason a cancel was asked for; later requests keep it."""
        if self.cancel_reason is None:
            self.cancel_reason = reason


def status_for_action_outcome(outcome: ServerOutcome, spec: TaskSpec) -> TaskStatus:
    """End status of an action task from how its server ended the goal."""
    if outcome is ServerOutcome.SUCCEEDED:
        return TaskStatus.DONE
    if outcome is ServerOutcome.CANCELED:
        return TaskStatus.DONE if spec.cancel_reported_as_success else TaskStatus.CANCELED
    return TaskStatus.ERROR


def status_for_service_response(response: dict[str, Any], spec: TaskSpec) -> TaskStatus:
    """End status of a service task: DONE, unless its success field says false."""
    if spec.service_success_field and response.get(spec.service_success_field) is False:
        return TaskStatus.ERROR
    return TaskStatus.DONE
