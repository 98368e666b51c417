"""A node's timeouts on one timer of it, armed for the earliest.

A timer made and destroyed for each bounded wait (a goal's answer, a service call's response)
costs rcl's making and destroying of a timer and, in the executor, a wait set made again for
the node's changed list of timers: twice per task. Here every timeout of a node is kept in
core's Deadlines and one timer, made once, is armed for the earliest (`DeadlinesOnTimer`, which
the node's DeadlineTimer of its tasks' deadlines is too). The actions run in the node's
executor, as a timer's callback would.
"""

import itertools
import threading
import time
import weakref
from collections.abc import Callable, Hashable

from rclpy.node import Node

from task_manager.core.admission.deadlines import Deadlines

# the longest the timer is armed for: a later timeout is armed again when it finds nothing due,
# and no delay can overflow rcl's signed 64-bit nanoseconds
_LONGEST_ARM_SEC = 3600.0

_of_node: 'weakref.WeakKeyDictionary[Node, Timeouts]' = weakref.WeakKeyDictionary()
_of_node_lock = threading.Lock()


class DeadlinesOnTimer:
    """Keyed actions due at times, run by one timer of the node armed for the earliest (in the
    node's executor, as a timer's callback). A key set again replaces its pending action."""

    def __init__(self, node: Node) -> None:
        self._deadlines = Deadlines()
        self._lock = threading.Lock()
        self._armed_at: float | None = None
        self._timer = node.create_timer(_LONGEST_ARM_SEC, self._on_timer)
        self._timer.cancel()

    def _set_deadline(self, key: Hashable, delay_sec: float, action: Callable[[], None]) -> None:
        at = time.monotonic() + delay_sec
        with self._lock:
            self._deadlines.set(key, at, action)
            if self._armed_at is None or at < self._armed_at:
                self._arm()

    def _clear_deadline(self, key: Hashable) -> None:
        with self._lock:
            self._deadlines.clear(key)

    def _arm(self) -> None:
        """Fire once at the earliest deadline, or never when there is none: a timer that finds
        nothing due when it fires (at most an hour later) arms itself again."""
        self._armed_at = at = self._deadlines.next_at()
        if at is None:
            self._timer.cancel()
            return
        delay_sec = at - time.monotonic()
        if not delay_sec < _LONGEST_ARM_SEC:  # NaN too
            delay_sec = _LONGEST_ARM_SEC
        self._timer.timer_period_ns = max(int(delay_sec * 1e9), 1)
        self._timer.reset()

    def _on_timer(self) -> None:
        with self._lock:
            due = self._deadlines.pop_due(time.monotonic())
            self._arm()  # first: an action that sets a deadline arms for it if it comes earlier
        run_each(due)


class Timeouts(DeadlinesOnTimer):
    """Actions due after a delay, run by one timer of the node."""

    def __init__(self, node: Node) -> None:
        super().__init__(node)
        self._keys = itertools.count()

    def after(self, delay_sec: float, action: Callable[[], None]) -> Hashable:
        """Run `action` once `delay_sec` has passed, unless cancelled with the key returned."""
        key = next(self._keys)
        self._set_deadline(key, delay_sec, action)
        return key

    def cancel(self, key: Hashable) -> None:
        """Forget the action of `key` (nothing when it has run)."""
        self._clear_deadline(key)


def run_each(actions: list[Callable[[], None]]) -> None:
    """Run every action due; one that raises (a bug) loses none of the others, and the first
    error is raised once all have run (the node's loop logs it and goes on)."""
    errors = []
    for action in actions:
        try:
            action()
        except Exception as error:
            errors.append(error)
    if errors:
        raise errors[0]


def timeouts_of(node: Node) -> Timeouts:
    """The node's Timeouts, made on first use."""
    with _of_node_lock:
        timeouts = _of_node.get(node)
        if timeouts is None:
            timeouts = _of_node[node] = Timeouts(node)
        return timeouts
