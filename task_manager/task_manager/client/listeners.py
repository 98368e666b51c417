"""How updates reach whoever waits for them: the executor thread puts each update to the
listeners of its kind; an iterator drains its own inbox, with bounded waits; a user's callback
is called, and what it raises is logged, not spread."""

import queue
import threading
import traceback
from collections.abc import Callable, Iterator
from enum import Enum
from typing import Any, Generic, Protocol, TypeVar

from rclpy.task import Future

from task_manager.core.bounds import UPDATES_UNREAD_MAX, check_wait_seconds
from task_manager.core.errors import FellBehind
from task_manager.rclpy_tools.log import NodeLog

T = TypeVar('T')
T_contra = TypeVar('T_contra', contravariant=True)


class End(Enum):
    """Put in an inbox to end the iteration over it."""

    OF_UPDATES = 'end of updates'
    """The `until` future of the iteration completed."""


class _Dropped:
    """In an inbox, where it began to drop updates; how many it has dropped so far."""

    def __init__(self) -> None:
        self.count = 1


class Inbox(Generic[T]):
    """What the executor thread puts for one iterator of updates (it never waits), and the end
    marker. Past `max_unread` unread updates it drops the next ones, counted, and its reader
    gets FellBehind in their place (`drain`): a caller that holds an iterator and stops reading
    cannot grow the process without bound."""

    def __init__(self, max_unread: int = UPDATES_UNREAD_MAX) -> None:
        self._queue: queue.SimpleQueue[T | End | _Dropped] = queue.SimpleQueue()
        self._max_unread = max_unread
        self._dropped: _Dropped | None = None

    def put(self, item: T | End, /) -> None:
        if item is End.OF_UPDATES:  # always kept: the iteration must be able to end
            self._queue.put(item)
        elif self._dropped is not None:  # the reader stops where dropping began
            self._dropped.count += 1
        elif self._queue.qsize() >= self._max_unread:
            self._dropped = _Dropped()
            self._queue.put(self._dropped)
        else:
            self._queue.put(item)

    def get(self, timeout_sec: float | None) -> 'T | End | _Dropped':
        """The next item; queue.Empty after `timeout_sec` (None: wait for good)."""
        return self._queue.get(timeout=timeout_sec)

    @property
    def max_unread(self) -> int:
        return self._max_unread


class Listener(Protocol[T_contra]):
    """Where the executor thread puts updates of one kind (an inbox may take more kinds)."""

    def put(self, item: T_contra, /) -> None: ...


class Callback(Generic[T]):
    """Hands items to a user's callback; what the callback raises is logged, not spread."""

    def __init__(self, callback: Callable[[T], None], log: NodeLog) -> None:
        self._callback = callback
        self._log = log

    def put(self, item: T, /) -> None:
        try:
            self._callback(item)
        except Exception:  # the callback boundary: the executor must go on
            self._log.error(f'callback {self._callback!r} failed:\n{traceback.format_exc()}')


class Listeners(Generic[T]):
    """The listeners of one kind of update, guarded by the client's lock."""

    def __init__(self, lock: threading.Condition) -> None:
        self._lock = lock
        self._listeners: list[Listener[T]] = []

    def add(self, listener: Listener[T]) -> Callable[[], None]:
        """Have `listener` get every update from now on; returns what stops it."""
        with self._lock:
            self._listeners.append(listener)
        return lambda: self.remove(listener)

    def remove(self, listener: Listener[T]) -> None:
        with self._lock:
            if listener in self._listeners:
                self._listeners.remove(listener)

    def put(self, item: T) -> None:
        """Give `item` to every listener, under the lock (so each gets the updates in order)."""
        with self._lock:
            for listener in self._listeners:
                listener.put(item)

    def copy(self) -> list[Listener[T]]:
        """The listeners now, to give them an update without the lock."""
        with self._lock:
            return list(self._listeners)


def drain(inbox: Inbox[T], timeout_sec: float | None, until: Future[Any] | None) -> Iterator[T]:
    """What arrives in `inbox`, until `timeout_sec` passes without any or `until` completes."""
    check_wait_seconds(timeout_sec)
    if until is not None:
        until.add_done_callback(lambda _: inbox.put(End.OF_UPDATES))
    while True:
        try:
            item = inbox.get(timeout_sec)
        except queue.Empty:
            return
        if item is End.OF_UPDATES:
            return
        if isinstance(item, _Dropped):
            raise FellBehind(
                f'this iterator kept {inbox.max_unread} updates unread and dropped the next '
                f'({item.count} so far): read it faster, or read again what it follows '
                '(task_states(), history(after_sequence=...), active_tasks())'
            )
        yield item
