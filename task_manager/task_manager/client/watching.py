"""Watching the Task Manager: its active task list, and iterators and callbacks over what it
publishes (active lists, results, task events)."""

import queue
import weakref
from collections.abc import Callable, Iterator
from typing import Any, TypeVar

from rclpy.task import Future
from task_manager_msgs.msg import ActiveTaskArray

from task_manager.client.connection import Connection, EventFeed
from task_manager.client.listeners import Callback, Inbox, Listeners, drain
from task_manager.client.records import ActiveTaskInfo, TaskEvent, TaskResult, status_of
from task_manager.core.errors import TaskManagerUnavailable
from task_manager.core.names import ACTIVE_TASKS_TOPIC
from task_manager.rclpy_tools import qos

T = TypeVar('T')


class ActiveTasks:
    """The latest /task_manager/active_tasks, and who listens for the next."""

    def __init__(self, connection: Connection) -> None:
        self._connection = connection
        self._latest: list[ActiveTaskInfo] | None = None
        self.listeners = Listeners[list[ActiveTaskInfo]](connection.lock)
        connection.subscribe(
            ActiveTaskArray, ACTIVE_TASKS_TOPIC, qos.LATEST_ACTIVE_TASKS, self._on_active
        )

    def latest(self, timeout_sec: float | None = None) -> list[ActiveTaskInfo]:
        """The latest list; waits for the first, then TaskManagerUnavailable."""
        timeout_sec = self._connection.timeout_sec if timeout_sec is None else timeout_sec
        lock = self._connection.lock
        with lock:
            if not lock.wait_for(lambda: self._latest is not None, timeout_sec):
                raise TaskManagerUnavailable(f'no active task list within {timeout_sec} s')
            return list(self._latest or [])

    def has(self, task_id: str) -> bool:
        """Whether the latest list has this task."""
        return any(t.task_id == task_id for t in self._latest or [])

    def _on_active(self, message: ActiveTaskArray) -> None:
        active = [
            ActiveTaskInfo(t.task_id, t.task_name, status_of(t.task_status, ended=False), t.source)
            for t in message.active_tasks
        ]
        with self._connection.lock:
            self._latest = active
            self.listeners.put(active)
            self._connection.lock.notify_all()


class Watch:
    """Iterators and callbacks over the active lists, the results and the task events."""

    def __init__(
        self,
        connection: Connection,
        active: ActiveTasks,
        results: Listeners[TaskResult],
        events: EventFeed,
    ) -> None:
        self._logger = connection.node.get_logger()
        self._active = active
        self._results = results
        self._events = events

    def active_task_updates(
        self, timeout_sec: float | None, until: Future[Any] | None
    ) -> Iterator[list[ActiveTaskInfo]]:
        inbox: Inbox[list[ActiveTaskInfo]] = queue.SimpleQueue()
        with self._active.listeners.listening(inbox):
            yield from drain(inbox, timeout_sec, until)

    def results(self, timeout_sec: float | None, until: Future[Any] | None) -> Iterator[TaskResult]:
        inbox: Inbox[TaskResult] = queue.SimpleQueue()
        with self._results.listening(inbox):
            yield from drain(inbox, timeout_sec, until)

    def updates(
        self, timeout_sec: float | None, until: Future[Any] | None
    ) -> Iterator[list[ActiveTaskInfo] | TaskResult]:
        inbox: Inbox[list[ActiveTaskInfo] | TaskResult] = queue.SimpleQueue()
        with self._active.listeners.listening(inbox), self._results.listening(inbox):
            # annotated: mypy infers no T from `A | B | End` against `T | End` by itself
            arrivals: Iterator[list[ActiveTaskInfo] | TaskResult] = drain(inbox, timeout_sec, until)
            yield from arrivals

    def task_events(
        self, timeout_sec: float | None, until: Future[Any] | None
    ) -> Iterator[TaskEvent]:
        """Every event from this call on (not from the first `next()`)."""
        self._events.follow()
        inbox: Inbox[TaskEvent] = queue.SimpleQueue()
        listeners = self._events.listeners
        listeners.add(inbox)
        events = _drain_then_stop(listeners, inbox, timeout_sec, until)
        # an iterator dropped before its first next() never runs its `finally`
        weakref.finalize(events, listeners.remove, inbox)
        return events

    def on_task_event(self, callback: Callable[[TaskEvent], None]) -> Callable[[], None]:
        self._events.subscribe()
        return self._events.listeners.add(Callback(callback, self._logger))


def _drain_then_stop(
    listeners: Listeners[T], inbox: Inbox[T], timeout_sec: float | None, until: Future[Any] | None
) -> Iterator[T]:
    try:
        yield from drain(inbox, timeout_sec, until)
    finally:
        listeners.remove(inbox)
