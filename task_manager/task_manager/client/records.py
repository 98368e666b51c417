"""The client's records of tasks, from the Task Manager's messages: how a task ended
(`TaskResult`), its state at one moment (`TaskState`) with its pauses (`Pause`) and the
decisions taken about it (`Decision`), an entry of the active list (`ActiveTaskInfo`) and one
change of a task (`TaskEvent`).

A paused task stays active (status PAUSED); its running time does not count the time paused.
A status, error code or event kind this client does not know (from a newer Task Manager) is
mapped to a known one and logged once, never raised: the messages are read on the client's
executor thread, which must go on.
"""

import json
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime, timedelta
from enum import StrEnum
from typing import Any, TypeGuard

from task_manager.client.message_values import datetime_of, datetime_of_epoch, json_object
from task_manager.core.status import ErrorCode, TaskStatus

LOG = logging.getLogger('task_manager.client')
# key: (what, the unknown value), noted once logged
_logged_unknown: set[tuple[str, str]] = set()


def _unknown(what: str, text: str, taken_as: str) -> None:
    """Log, once per value, a value of a newer Task Manager that this client does not know."""
    if (what, text) not in _logged_unknown:
        _logged_unknown.add((what, text))
        LOG.warning(
            'the Task Manager sent the %s %r, which this client does not know (a newer Task '
            'Manager?): taken as %r',
            what,
            text,
            taken_as,
        )


def status_of(text: str, ended: bool) -> TaskStatus:
    """A task status from a message; one this client does not know is ERROR once the task
    has `ended`, else RECEIVED (active, not started)."""
    try:
        return TaskStatus(text)
    except ValueError:
        status = TaskStatus.ERROR if ended else TaskStatus.RECEIVED
        _unknown('task status', text, str(status))
        return status


def error_code_of(text: str) -> ErrorCode:
    """An error code from a message; one this client does not know is NONE (the result's
    `error` still says why)."""
    try:
        return ErrorCode(text)
    except ValueError:
        _unknown('error code', text, '')
        return ErrorCode.NONE


@dataclass(frozen=True)
class Pause:
    """One pause of a task: when and by whom it was paused, and resumed."""

    paused_at: datetime
    paused_by: str
    """The source of the system/pause task that paused it."""
    resumed_at: datetime | None = None
    """None while it is paused (or if it ended paused)."""
    resumed_by: str = ''
    """The source of the system/resume task; '' while it is paused."""

    def length(self, until: datetime) -> timedelta:
        """How long it was paused before `until` (an open pause lasts until then)."""
        end = until if self.resumed_at is None else min(self.resumed_at, until)
        return max(end - self.paused_at, timedelta(0))


def parse_pauses(text: str) -> list[Pause]:
    """The pauses of a TaskState's `pauses` JSON; items that are not pauses are left out."""
    try:
        items = json.loads(text or '[]')
    except json.JSONDecodeError:
        return []
    if not isinstance(items, list):
        return []
    return [pause for item in items if (pause := _pause(item)) is not None]


def _pause(item: Any) -> Pause | None:
    if not isinstance(item, dict):
        return None
    paused, resumed = item.get('paused'), item.get('resumed')
    if not _is_epoch(paused) or not (resumed is None or _is_epoch(resumed)):
        return None
    return Pause(
        paused_at=datetime_of_epoch(paused),
        paused_by=str(item.get('paused_by') or ''),
        resumed_at=None if resumed is None else datetime_of_epoch(resumed),
        resumed_by=str(item.get('resumed_by') or ''),
    )


def _is_epoch(value: Any) -> TypeGuard[float]:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def paused_time(pauses: Sequence[Pause], paused: timedelta, until: datetime) -> timedelta:
    """Time paused before `until`: from `pauses` when known (an open pause still counts),
    else `paused` (the task's paused_sec)."""
    if not pauses:
        return paused
    return sum((pause.length(until) for pause in pauses), timedelta(0))


def running_time(
    started_at: datetime, until: datetime, pauses: Sequence[Pause], paused: timedelta
) -> timedelta:
    """From `started_at` to `until`, less the time paused: the clock stops while paused."""
    return max(until - started_at - paused_time(pauses, paused, until), timedelta(0))


@dataclass(frozen=True)
class Decision:
    """One decision the Task Manager took about a task, and why, in words that name the other
    party ("queued behind drive-1 (priority 5), which holds base")."""

    at: datetime
    decision: str
    """queued, started, refused, preempted, timeout, retry or reprioritized (a newer Task
    Manager may add others); `omitted` where decisions were left out (a task keeps at most
    DECISIONS_PER_TASK_MAX: its first and its newest)."""
    reason: str
    omitted: int = 0
    """Of an `omitted` entry: how many decisions were left out in its place."""


def parse_decisions(text: str) -> list[Decision]:
    """The decisions of a TaskState's `decisions` JSON; items that are not decisions are left
    out."""
    try:
        items = json.loads(text or '[]')
    except json.JSONDecodeError:
        return []
    if not isinstance(items, list):
        return []
    return [
        Decision(
            datetime_of_epoch(item['at']),
            str(item['decision']),
            str(item.get('reason', '')),
            _count(item.get('omitted')),
        )
        for item in items
        if isinstance(item, dict) and _is_epoch(item.get('at')) and item.get('decision')
    ]


def _count(value: Any) -> int:
    """A count that is not a non-negative whole number reads as 0."""
    return value if isinstance(value, int) and not isinstance(value, bool) and value > 0 else 0


@dataclass(frozen=True)
class TaskResult:
    """How a task ended.

    The stamps are None when unknown: /task_manager/results and the ExecuteTask result carry
    none, so results from `results()` have none; a TaskHandle's result, `recent_results()`
    and the ENDED events of `task_events()` have them.
    """

    task_id: str
    task_name: str
    status: TaskStatus
    error_code: ErrorCode
    result: dict[str, Any]
    source: str = ''
    received_at: datetime | None = None
    """When the Task Manager received the task."""
    started_at: datetime | None = None
    """When it started on its server; None also when it never started."""
    ended_at: datetime | None = None
    paused: timedelta = timedelta(0)
    """How long it was paused (known with the stamps)."""

    @property
    def ok(self) -> bool:
        return self.status is TaskStatus.DONE

    @property
    def duration(self) -> timedelta | None:
        """How long it ran: from its start to its end, less the time it was paused; None if it
        never started or unknown."""
        if self.started_at is None or self.ended_at is None:
            return None
        return max(self.ended_at - self.started_at - self.paused, timedelta(0))

    @property
    def error_message(self) -> str:
        """Why the Task Manager refused or failed the task (its `error`), or ''."""
        error = self.result.get('error')
        return error if isinstance(error, str) else ''

    @classmethod
    def from_message(cls, message: Any, task_name: str = '', source: str = '') -> 'TaskResult':
        """From a TaskDoneResult, or an ExecuteTask result with the goal's name and source."""
        return cls(
            task_id=message.task_id,
            task_name=getattr(message, 'task_name', '') or task_name,
            status=status_of(message.task_status, ended=True),
            error_code=error_code_of(message.error_code),
            result=json_object(message.task_result),
            source=getattr(message, 'source', '') or source,
        )

    def with_stamps_of(self, state: 'TaskState') -> 'TaskResult':
        """This result with the stamps (and time paused) of `state` (the same task's)."""
        return replace(
            self,
            received_at=state.received_at,
            started_at=state.started_at,
            ended_at=state.ended_at,
            paused=state.paused_before_end(),
        )


@dataclass(frozen=True)
class ActiveTaskInfo:
    """One entry of /task_manager/active_tasks (which carries no stamps: see TaskState)."""

    task_id: str
    task_name: str
    status: TaskStatus
    source: str


@dataclass(frozen=True)
class TaskState:
    """Everything known of one task at one moment: a TaskState message, with datetimes.

    Its first fields are those of ActiveTaskInfo, so it can stand in for one.
    """

    task_id: str
    task_name: str
    status: TaskStatus
    source: str
    error_code: ErrorCode = ErrorCode.NONE
    mission_id: str = ''
    """The id of the mission this task is a subtask of; '' when it is none's."""
    received_at: datetime | None = None
    started_at: datetime | None = None
    """When it started on its server; None while it has not (or never did)."""
    ended_at: datetime | None = None
    feedback: dict[str, Any] | None = None
    """The latest feedback; None before the first."""
    result: dict[str, Any] | None = None
    """The result once the task has ended; None before."""
    sequence: int = 0
    """Once ended: its number in the task history (only grows, never repeats); 0 before."""
    paused: timedelta = timedelta(0)
    """Time spent paused (the message's paused_sec)."""
    pauses: list[Pause] = field(default_factory=list)
    """Each pause, oldest first; the last is still open while the task is PAUSED."""
    queue_position: int = 0
    """While QUEUED: its place in the queue, 1 first; else 0."""
    priority: int = 0
    """The priority the Task Manager decided with (higher wins)."""
    attempt: int = 1
    """Which attempt this is, 1 first; more once a declared retry started it again."""
    decisions: list[Decision] = field(default_factory=list)
    """Every decision the Task Manager took about it, oldest first (see TaskManagerClient.why)."""

    @property
    def is_final(self) -> bool:
        return self.status.is_final

    def elapsed(self, now: datetime | None = None) -> timedelta | None:
        """How long it has run: from its start to its end, or to `now` (default: the present),
        less the time paused (the clock stops while it is paused).

        None if it has not started. The stamps are the Task Manager's wall clock.
        """
        if self.started_at is None:
            return None
        end = self.ended_at or now or datetime.now(UTC)
        return running_time(self.started_at, end, self.pauses, self.paused)

    def paused_before_end(self) -> timedelta:
        """Time paused, up to its end once ended (a task may end while paused)."""
        if self.ended_at is None:
            return self.paused
        return paused_time(self.pauses, self.paused, self.ended_at)

    def to_result(self) -> TaskResult:
        """The TaskResult of an ended task (of one still active: its result so far, `{}`)."""
        return TaskResult(
            task_id=self.task_id,
            task_name=self.task_name,
            status=self.status,
            error_code=self.error_code,
            result=self.result or {},
            source=self.source,
            received_at=self.received_at,
            started_at=self.started_at,
            ended_at=self.ended_at,
            paused=self.paused_before_end(),
        )

    @classmethod
    def from_message(cls, message: Any) -> 'TaskState':
        """From a task_manager_msgs/msg/TaskState."""
        ended_at = datetime_of(message.ended)
        return cls(
            task_id=message.task_id,
            task_name=message.task_name,
            status=status_of(message.task_status, ended=ended_at is not None),
            source=message.source,
            error_code=error_code_of(message.error_code),
            mission_id=message.mission_id,
            received_at=datetime_of(message.received),
            started_at=datetime_of(message.started),
            ended_at=ended_at,
            feedback=json_object(message.feedback) if message.feedback else None,
            result=json_object(message.task_result) if message.task_result else None,
            sequence=message.sequence,
            paused=timedelta(seconds=max(message.paused_sec, 0.0)),
            pauses=parse_pauses(message.pauses),
            queue_position=message.queue_position,
            priority=message.priority,
            attempt=message.attempt or 1,
            decisions=parse_decisions(message.decisions),
        )


class TaskEventKind(StrEnum):
    """Which change of a task a TaskEvent reports."""

    RECEIVED = 'RECEIVED'
    """The Task Manager received the request (every request has one)."""
    QUEUED = 'QUEUED'
    """It waits in the queue for its resources (`reason` says behind whom)."""
    STARTED = 'STARTED'
    """The task started on its server (not for a request refused before starting)."""
    FEEDBACK = 'FEEDBACK'
    """New feedback (at most `feedback_rate_hz` a second; the latest wins)."""
    PAUSED = 'PAUSED'
    """system/pause paused the task (its status is PAUSED; it is still active)."""
    RESUMED = 'RESUMED'
    """system/resume resumed the task (its status is IN_PROGRESS again)."""
    DECIDED = 'DECIDED'
    """The Task Manager decided something else about it (a new priority, a retry); also any
    change this client does not know (from a newer Task Manager)."""
    ENDED = 'ENDED'
    """The task ended (the last event of a task)."""


@dataclass(frozen=True)
class TaskEvent:
    """One message of /task_manager/task_events."""

    kind: TaskEventKind
    stamp: datetime
    """When the change happened (the Task Manager's wall clock)."""
    task: TaskState
    """The task's state just after the change."""
    reason: str = ''
    """Why, when the Task Manager decided it (queued, refused, pre-empted, timed out,
    retried), naming the other party; '' otherwise."""

    @classmethod
    def from_message(cls, message: Any) -> 'TaskEvent':
        """From a task_manager_msgs/msg/TaskEvent."""
        stamp = datetime_of(message.stamp) or datetime.fromtimestamp(0, UTC)
        task = TaskState.from_message(message.task)
        return cls(event_kind_of(message.event), stamp, task, message.reason)


@dataclass(frozen=True)
class EventsLost:
    """In `task_events(losses=True)`, where task events went missing (see `on_events_lost`):
    what a caller keeps from the events should be read again (`task_states`)."""

    batches: int
    """How many batches of events (up to 100 events each) were lost; 0: not known (see
    `on_events_lost`)."""


def event_kind_of(text: str) -> TaskEventKind:
    """An event kind from a message; one this client does not know is DECIDED (some other
    change: the event's state says what the task is now)."""
    try:
        return TaskEventKind(text)
    except ValueError:
        _unknown('event kind', text, str(TaskEventKind.DECIDED))
        return TaskEventKind.DECIDED
