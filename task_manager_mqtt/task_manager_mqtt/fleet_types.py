"""What the FleetClient takes and gives back: its error, its view of a robot, a task started
on a robot, and the keywords of a start's options and of a schedule."""

from concurrent.futures import Future
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any, TypedDict

from task_manager.protocol.errors import RefusalCode

TIMEOUT_SEC = 10.0

Document = dict[str, Any]


class FleetError(Exception):
    """A request the robot refused (its error code and message), or no answer in time."""

    def __init__(self, message: str, code: str = '') -> None:
        super().__init__(message)
        self.code = code


@dataclass
class RobotView:
    """What is known of one robot, from its retained topics."""

    robot_id: str
    connection: Document | None = None
    active_tasks: list[Document] = field(default_factory=list)
    active_tasks_omitted: int = 0
    """Active tasks left out of `active_tasks` so that its message fit the broker's limit."""
    tasks: list[Document] = field(default_factory=list)
    last_sequence: int = 0
    """Of the last result passed on (one that comes again with the same sequence and task id
    is a duplicate; a lower one with another task is passed on: a new history of the robot)."""
    duplicates: int = 0
    """Results delivered again (after a reconnection) and not passed on."""

    @property
    def online(self) -> bool:
        return bool(self.connection and self.connection.get('connection_state') == 'ONLINE')

    @property
    def dead_letters(self) -> int:
        """Request messages its bridge could not answer since it started (see on_dead_letter)."""
        return int((self.connection or {}).get('dead_letters') or 0)


@dataclass
class FleetTask:
    """A task or mission started on a robot: its reply, then its result (Task documents)."""

    robot_id: str
    task_id: str
    reply_future: Future[Document]
    result_future: Future[Document]

    def accepted(self, timeout_sec: float = TIMEOUT_SEC) -> Document:
        """The robot's reply (FleetError if it refused the request)."""
        return outcome(self.reply_future, timeout_sec, f'reply of {self.robot_id}')

    def result(self, timeout_sec: float = TIMEOUT_SEC) -> Document:
        """The ended task (a Task document with its status, error code and result)."""
        return outcome(self.result_future, timeout_sec, f'result of {self.task_id}')


class Reply(TypedDict, total=False):
    """What a robot's reply to a FleetClient's request holds besides its address and outcome
    (protocol/mqtt.py's MqttReply): each call returns one of these."""

    task: Document
    tasks: list[Document]
    decisions: list[Document]
    paused: Document
    resumed: Document
    scheduled: Document
    schedules: list[Document]
    confirmed: Document


class StartOptions(TypedDict, total=False):
    """The options of a start (StartTask's); each left out takes the robot's declaration."""

    priority: int
    on_conflict: str
    """preempt, queue or reject."""
    timeout_sec: float
    queue_timeout_sec: float
    feedback_timeout_sec: float


class ScheduleFields(StartOptions, total=False):
    """A schedule's fields beside what it runs (ScheduleTask's): exactly one of at, delay_sec,
    period_sec, cron; the options are each run's."""

    schedule_id: str
    at: datetime | str
    """Once, at this time (aware; or ISO 8601 text with its zone)."""
    delay_sec: float
    period_sec: float
    cron: str
    time_zone: str
    window_start: datetime | str
    window_end: datetime | str
    max_runs: int
    overlap: str
    """SKIP (the default), BUFFER_ONE, CANCEL_OTHER or ALLOW_ALL."""
    misfire_grace_sec: float


def schedule_document(fields: ScheduleFields) -> Document:
    """The JSON fields of a schedule request (datetimes as ISO 8601 text)."""
    return {
        name: value.isoformat() if isinstance(value, datetime) else value
        for name, value in fields.items()
    }


def outcome(future: Future[Document], timeout_sec: float, what: str) -> Document:
    """The reply `future` completes with; FleetError if it is an error reply or comes not in
    time."""
    try:
        return _checked(future.result(timeout_sec))
    except TimeoutError:
        raise FleetError(f'no {what} within {timeout_sec} s', RefusalCode.TIMEOUT) from None


def _checked(reply: Document) -> Document:
    """The reply; FleetError with its code if it is an error reply."""
    if reply.get('ok') is False:
        error = reply.get('error') or {}
        raise FleetError(error.get('message', 'refused'), error.get('code', ''))
    return reply
