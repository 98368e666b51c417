"""Watching the Task Manager: its active task list, and iterators and callbacks over what it
publishes (active lists, results, task events)."""

import weakref
from collections.abc import Callable, Iterator
from typing import Any, Literal, TypeVar, overload

from rclpy.node import Node
from rclpy.serialization import deserialize_message
from rclpy.subscription import MessageInfo
from rclpy.task import Future
from task_manager_msgs.msg import ActiveTaskArray

from task_manager.client.connection import Connection, EventFeed, Place, place_of
from task_manager.client.listeners import Callback, Inbox, Listeners, drain
from task_manager.client.records import (
    ActiveTaskInfo,
    EventsLost,
    TaskEvent,
    TaskResult,
    status_of,
)
from task_manager.core.bounds import check_wait_seconds
from task_manager.core.errors import TaskManagerUnavailable
from task_manager.core.names import ACTIVE_TASKS_TOPIC
from task_manager.rclpy_tools import qos
from task_manager.rclpy_tools.log import NodeLog

T = TypeVar('T')

# The key of the deep reader of the active lists, beside the topic's own (the latest list).
EVERY_ACTIVE_LIST = f'{ACTIVE_TASKS_TOPIC} (every list)'


class ActiveTasks:
    """The latest /task_manager/active_tasks, and who listens for every list.

    Two readers of the topic: the latest list comes from one that keeps only the newest (a
    client that joins gets the current list, not the publisher's history); the listeners get
    every list from a deep one, made on first use, so that a list shown for a moment (a task
    that starts and ends within a tick) is not overwritten before they see it. The deep reader
    is transient local: the lists published while the Task Manager's writer is still learning
    of it come as its history. Of that history, the lists up to the latest one the client had
    when it started following are dropped: they are over.

    The latest list is kept as its bytes and read when asked for: a client that never asks
    (a gateway follows the events) does not convert each list, as long as the active tasks,
    into Python (3 ms for 500 tasks).
    """

    def __init__(self, connection: Connection) -> None:
        self._connection = connection
        self._latest_bytes: bytes | None = None
        self._latest: list[ActiveTaskInfo] | None = None
        """`_latest_bytes` read, once asked for (None until then)."""
        self._latest_place: Place | None = None
        self._followed_from: Place | None = None
        self._following = False
        self.listeners = Listeners[list[ActiveTaskInfo]](connection.lock)
        """Who gets every list from `follow()` on."""
        connection.subscribe(
            ActiveTaskArray,
            ACTIVE_TASKS_TOPIC,
            qos.LATEST_ACTIVE_TASKS,
            self._on_latest,
            with_info=True,
            raw=True,
        )

    def latest(self, timeout_sec: float | None = None) -> list[ActiveTaskInfo]:
        """The latest list; waits for the first, then TaskManagerUnavailable."""
        check_wait_seconds(timeout_sec)
        timeout_sec = self._connection.timeout_sec if timeout_sec is None else timeout_sec
        lock = self._connection.lock
        with lock:
            if not lock.wait_for(lambda: self._latest_bytes is not None, timeout_sec):
                raise TaskManagerUnavailable(f'no active task list within {timeout_sec} s')
            return list(self._read_latest())

    def has(self, task_id: str) -> bool:
        """Whether the latest list has this task (call it holding the client's lock)."""
        return any(t.task_id == task_id for t in self._read_latest())

    def _read_latest(self) -> list[ActiveTaskInfo]:
        """The latest list read from its bytes, once (the client's lock held)."""
        if self._latest is None and self._latest_bytes is not None:
            self._latest = _infos(deserialize_message(self._latest_bytes, ActiveTaskArray))
        return self._latest or []

    def follow(self) -> None:
        """Subscribe (once) to every list; wait until the Task Manager's publisher reaches
        it, if a Task Manager is there (bounded by the client's timeout)."""
        lock = self._connection.lock
        if self._connection.connected:
            with lock:  # the list of the moment arrives with the match: wait, to know it
                lock.wait_for(lambda: self._latest_bytes is not None, self._connection.timeout_sec)
        with lock:
            subscribe = not self._following
            self._following = True
            if subscribe:
                self._followed_from = self._latest_place
        if subscribe:
            self._connection.subscribe(
                ActiveTaskArray,
                ACTIVE_TASKS_TOPIC,
                qos.ACTIVE_TASK_CHANGES,
                self._on_change,
                key=EVERY_ACTIVE_LIST,
                with_info=True,
            )
        if self._connection.connected:
            self._connection.wait_matched({EVERY_ACTIVE_LIST}, self._connection.timeout_sec)

    def _on_latest(self, message: bytes, info: MessageInfo) -> None:
        with self._connection.lock:
            self._latest_bytes, self._latest = message, None
            self._latest_place = place_of(info)
            self._connection.lock.notify_all()

    def _on_change(self, message: ActiveTaskArray, info: MessageInfo) -> None:
        writer, number = place_of(info)
        start = self._followed_from
        if start is not None and writer == start[0] and number <= start[1]:
            return  # history from before follow()
        self.listeners.put(_infos(message))


def _infos(message: ActiveTaskArray) -> list[ActiveTaskInfo]:
    return [
        ActiveTaskInfo(t.task_id, t.task_name, status_of(t.task_status, ended=False), t.source)
        for t in message.active_tasks
    ]


class Watching:
    """TaskManagerClient's watching of what the Task Manager publishes: the active list, and
    iterators and callbacks over the active lists, the results and the task events."""

    node: Node
    _active: ActiveTasks
    _results: Listeners[TaskResult]
    """Who gets every result of /task_manager/results (the client's tasks put them)."""
    _events: EventFeed

    def active_tasks(self, timeout_sec: float | None = None) -> list[ActiveTaskInfo]:
        """The current active tasks (the latest /task_manager/active_tasks message)."""
        return self._active.latest(timeout_sec)

    def active_task_updates(
        self, timeout_sec: float | None = None, until: Future[Any] | None = None
    ) -> Iterator[list[ActiveTaskInfo]]:
        """Every active task list from this call on.

        Like every iterator here, it keeps what comes from the call, not from its first
        `next()`: call it, then read what the lists will change (taskctl active --watch: the
        task states), or start the tasks it must not miss. Stops after `timeout_sec` without
        an update (None: never), or once `until` completes.
        """
        self._active.follow()
        inbox: Inbox[list[ActiveTaskInfo]] = Inbox()
        return _from_now(inbox, self._active.listeners.add(inbox), timeout_sec, until)

    def results(
        self, timeout_sec: float | None = None, until: Future[Any] | None = None
    ) -> Iterator[TaskResult]:
        """Every task result from this call on; stops as active_task_updates does."""
        inbox: Inbox[TaskResult] = Inbox()
        return _from_now(inbox, self._results.add(inbox), timeout_sec, until)

    def updates(
        self, timeout_sec: float | None = None, until: Future[Any] | None = None
    ) -> Iterator[list[ActiveTaskInfo] | TaskResult]:
        """Active task lists and results from this call on, in the order they arrive; stops as
        active_task_updates does."""
        self._active.follow()
        inbox: Inbox[list[ActiveTaskInfo] | TaskResult] = Inbox()
        stops = [self._active.listeners.add(inbox), self._results.add(inbox)]
        return _from_now(inbox, lambda: [stop() for stop in stops], timeout_sec, until)

    @overload
    def task_events(
        self,
        timeout_sec: float | None = None,
        until: Future[Any] | None = None,
        *,
        losses: Literal[False] = False,
    ) -> Iterator[TaskEvent]: ...

    @overload
    def task_events(
        self,
        timeout_sec: float | None = None,
        until: Future[Any] | None = None,
        *,
        losses: Literal[True],
    ) -> Iterator[TaskEvent | EventsLost]: ...

    def task_events(
        self,
        timeout_sec: float | None = None,
        until: Future[Any] | None = None,
        *,
        losses: bool = False,
    ) -> Iterator[TaskEvent] | Iterator[TaskEvent | EventsLost]:
        """Every event of every task from this call on; stops as active_task_updates does.

        With `losses`, an EventsLost comes too wherever events went missing, in its place:
        after the events of the batch that showed the gap, as `on_events_lost` is called."""
        self._events.follow()
        inbox: Inbox[TaskEvent | EventsLost] = Inbox()
        stops = [self._events.listeners.add(inbox)]
        if losses:
            stops.append(self._events.lost.add(_LossesInto(inbox)))
        return _from_now(inbox, lambda: [stop() for stop in stops], timeout_sec, until)

    def on_task_event(self, callback: Callable[[TaskEvent], None]) -> Callable[[], None]:
        """Call `callback(event)` with every task event from now on; returns the unsubscribe.

        It runs on the executor thread: it must return quickly and never wait on the client.
        """
        self._events.subscribe()
        return self._events.listeners.add(Callback(callback, NodeLog.of(self.node)))

    def on_events_lost(self, callback: Callable[[int], None]) -> Callable[[], None]:
        """Call `callback(batches)` when task events went missing; returns the unsubscribe.

        A client that falls behind the Task Manager by more than its reader holds (1,000
        batches of up to 100 events) loses the oldest: `batches` of them, found from the
        numbers the middleware gives each message. `batches` is 0 when the events reach this
        client after the node already did (a node started or started again; 11-18 ms later
        here): what came between is not known. What a caller keeps from the events (an
        active list, a task's last state) should then be read again (`task_states`). It
        runs on the executor thread, after the events of the batch that showed the gap.
        """
        self._events.subscribe()
        return self._events.lost.add(Callback(callback, NodeLog.of(self.node)))


class _LossesInto:
    """Puts an EventsLost into an inbox of events for each loss told."""

    def __init__(self, inbox: Inbox[TaskEvent | EventsLost]) -> None:
        self._inbox = inbox

    def put(self, batches: int, /) -> None:
        self._inbox.put(EventsLost(batches))


def _from_now(
    inbox: Inbox[T],
    stop: Callable[[], object],
    timeout_sec: float | None,
    until: Future[Any] | None,
) -> Iterator[T]:
    """What `inbox` gets (it listens already) as an iterator; `stop` ends its listening when the
    iterator ends, or when it is dropped (one dropped before its first `next()` never runs its
    `finally`)."""
    items = _drain_then_stop(inbox, stop, timeout_sec, until)
    weakref.finalize(items, stop)
    return items


def _drain_then_stop(
    inbox: Inbox[T],
    stop: Callable[[], object],
    timeout_sec: float | None,
    until: Future[Any] | None,
) -> Iterator[T]:
    try:
        # annotated: mypy infers no T from `A | B | End` against `T | End` by itself
        items: Iterator[T] = drain(inbox, timeout_sec, until)
        yield from items
    finally:
        stop()
