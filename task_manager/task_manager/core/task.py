"""One task request and its lifecycle: RECEIVED -> IN_PROGRESS -> DONE | ERROR | CANCELED.

A started task may be PAUSED and resumed (back to IN_PROGRESS) any number of times; a paused
task may also end (cancelled, or a mission whose last subtask ends while it is paused).
"""

import json
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from task_manager.core.admission.decisions import DecisionKind, DecisionNote, keep_note, new_note
from task_manager.core.admission.options import RequestOptions
from task_manager.core.errors import InvalidTransition
from task_manager.core.status import CancelReason, ErrorCode, ServerOutcome, TaskStatus
from task_manager.core.task_spec import TaskSpec

# key: status, value: the statuses a task may move to from it
_ALLOWED_TRANSITIONS: dict[TaskStatus, frozenset[TaskStatus]] = {
    TaskStatus.RECEIVED: frozenset(
        {TaskStatus.QUEUED, TaskStatus.IN_PROGRESS, TaskStatus.ERROR, TaskStatus.CANCELED}
    ),
    TaskStatus.QUEUED: frozenset({TaskStatus.IN_PROGRESS, TaskStatus.ERROR, TaskStatus.CANCELED}),
    TaskStatus.IN_PROGRESS: frozenset(
        {TaskStatus.PAUSED, TaskStatus.DONE, TaskStatus.ERROR, TaskStatus.CANCELED}
    ),
    TaskStatus.PAUSED: frozenset(
        {TaskStatus.IN_PROGRESS, TaskStatus.DONE, TaskStatus.ERROR, TaskStatus.CANCELED}
    ),
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
    options: RequestOptions = field(default_factory=RequestOptions)
    """The request's own priority, on_conflict and timeouts (StartTask, the gateways)."""


@dataclass(frozen=True)
class TaskEnd:
    """How a task ended: status, result message as a dict, and error code."""

    status: TaskStatus
    result: dict[str, Any] = field(default_factory=dict)
    error_code: ErrorCode = ErrorCode.NONE


@dataclass
class PauseSpan:
    """One pause of a task: when and by whom it was paused, and resumed (if it was)."""

    paused_at: float
    paused_by: str
    resumed_at: float | None = None
    resumed_by: str = ''

    def to_dict(self) -> dict[str, Any]:
        return {
            'paused': self.paused_at,
            'paused_by': self.paused_by,
            'resumed': self.resumed_at,
            'resumed_by': self.resumed_by,
        }


def pauses_to_json(pauses: list[PauseSpan]) -> str:
    """Pauses as a compact JSON list ('[]' when never paused)."""
    return json.dumps([span.to_dict() for span in pauses], separators=(',', ':'))


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
    pauses: list[PauseSpan] = field(default_factory=list)
    """Each pause, oldest first; the last one is open while the task is PAUSED."""
    priority: int = 0
    """The priority it was admitted with (higher wins); system/reprioritize changes it."""
    queue_position: int = 0
    """While QUEUED: its place in the queue, 1 first."""
    attempt: int = 1
    """Which attempt runs (a declaration's retry starts it again under the same id)."""
    decisions: list[DecisionNote] = field(default_factory=list)
    """The decisions taken about it, oldest first (queued, refused, pre-empted, ...): at most
    DECISIONS_PER_TASK_MAX, the first and the newest, with a count of those left out between."""
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

    def _require(self, before: TaskStatus, status: TaskStatus) -> None:
        if self.status is not before:
            raise InvalidTransition(
                f'task {self.task_id}: cannot go from {self.status} to {status} this way'
            )

    def mark_queued(self, position: int) -> None:
        self._require(TaskStatus.RECEIVED, TaskStatus.QUEUED)
        self._move_to(TaskStatus.QUEUED)
        self.queue_position = position

    def mark_started(self, now: float | None = None) -> None:
        if self.status is not TaskStatus.QUEUED:
            self._require(TaskStatus.RECEIVED, TaskStatus.IN_PROGRESS)
        self._move_to(TaskStatus.IN_PROGRESS)
        self.queue_position = 0
        self.started_at = time.time() if now is None else now

    def note(self, decision: DecisionKind, reason: str, now: float | None = None) -> DecisionNote:
        """Keep a decision taken about this task, with its reason (see keep_note)."""
        entry = new_note(time.time() if now is None else now, decision, reason)
        keep_note(self.decisions, entry)
        return entry

    def mark_paused(self, by: str, now: float | None = None) -> None:
        """Paused at the request of source `by`."""
        self._move_to(TaskStatus.PAUSED)
        self.pauses.append(PauseSpan(time.time() if now is None else now, by))

    def mark_resumed(self, by: str, now: float | None = None) -> None:
        """Running again at the request of source `by`."""
        self._require(TaskStatus.PAUSED, TaskStatus.IN_PROGRESS)
        self._move_to(TaskStatus.IN_PROGRESS)
        self.pauses[-1].resumed_at = time.time() if now is None else now
        self.pauses[-1].resumed_by = by

    def paused_sec(self, now: float | None = None) -> float:
        """Time spent paused; a pause still open counts until the end, or `now`."""
        until = self.ended_at if self.ended_at is not None else time.time() if now is None else now
        return sum(
            (
                max((span.resumed_at if span.resumed_at is not None else until) - span.paused_at, 0)
                for span in self.pauses
            ),
            0.0,
        )

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
        self.queue_position = 0
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
