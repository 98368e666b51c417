"""The one way to say that a task changed: its event on /task_manager/task_events, its row in
the history and, when its place in /task_manager/active_tasks changed, that list.

A task's end is written to the history first and announced once committed (ENDED, the result
on /task_manager/results: see history_writer.py); the list that shows it ended once more is
queued at once, and goes out after the executor's turn.
"""

from collections.abc import Callable
from enum import Enum, auto
from typing import Protocol

from rclpy.node import Node
from rclpy.task import Future

from task_manager.core.history.store import TaskHistory
from task_manager.core.task import TaskRecord
from task_manager.ros.recording.active_tasks import ActiveTasksPublication
from task_manager.ros.recording.history_writer import HistoryWriter
from task_manager.ros.recording.task_events import TaskEventStream


class TaskReporter(Protocol):
    """Where the lists of active tasks and the results go (the node's publishers)."""

    def publish_active(self, records: list[TaskRecord]) -> None: ...

    def publish_result(self, record: TaskRecord) -> None: ...


class TaskChange(Enum):
    """How a task changed before its end; each has its event."""

    RECEIVED = auto()
    QUEUED = auto()
    STARTED = auto()
    DECIDED = auto()
    """A decision that changes no status: a priority changed, a retry planned."""
    PAUSED = auto()
    RESUMED = auto()


# the changes that move a task in or within the active list (a decision moves none by itself)
_LISTED = frozenset({TaskChange.QUEUED, TaskChange.STARTED, TaskChange.PAUSED, TaskChange.RESUMED})


class TaskChanges:
    """Records and announces every change of every task."""

    def __init__(
        self,
        node: Node,
        events: TaskEventStream,
        history: TaskHistory,
        reporter: TaskReporter,
        listed: Callable[[], list[TaskRecord]],
    ) -> None:
        """`listed`: the tasks active_tasks shows now."""
        self._events = events
        self._reporter = reporter
        self._history = HistoryWriter(node, history, self._announce_ends)
        self._active = ActiveTasksPublication(node, listed, reporter)

    def changed(self, record: TaskRecord, change: TaskChange, reason: str = '') -> None:
        """`record` changed (`reason`: why the Task Manager decided so, if it did)."""
        events = self._events
        if change is TaskChange.RECEIVED:
            events.received(record)
        elif change is TaskChange.QUEUED:
            events.queued(record, reason)
        elif change is TaskChange.STARTED:
            events.started(record, reason)
        elif change is TaskChange.DECIDED:
            events.decided(record, reason)
        elif change is TaskChange.PAUSED:
            events.paused(record)
        else:
            events.resumed(record)
        self._history.changed(record)
        if change in _LISTED:
            self._active.changed()

    def places_changed(self) -> None:
        """The queue moved: the places of the tasks waiting in it changed."""
        self._active.changed()

    def ended(self, record: TaskRecord, was_listed: bool) -> Future[None]:
        """`record` ended: the future completes once its end is stored and announced."""
        if was_listed:
            self._active.ended(record)
        return self._history.ended(record)

    def _announce_ends(self, records: list[TaskRecord]) -> None:
        """ENDED on the event stream (the batch out at once), then each result on
        /task_manager/results."""
        for record in records:
            self._events.ended(record)
        self._events.flush()
        for record in records:
            self._reporter.publish_result(record)
