"""A node's timeouts on one timer of it, armed for the earliest.

A timer made and destroyed for each bounded wait (a goal's answer, a service call's response)
costs rcl's making and destroying of a timer and, in the executor, a wait set made again for
the node's changed list of timers: twice per task. Here every timeout of a node is kept in
core's Deadlines and one timer, made once, is armed for the earliest, as the node's
DeadlineTimer does for its tasks' deadlines. The actions run in the node's executor, as a
timer's callback would.
"""

import itertools
import threading
import time
import weakref
from collections.abc import Callable, Hashable

from rclpy.node import Node
from rclpy.timer import Timer

from task_manager.core.admission.deadlines import Deadlines

# the longest the timer is armed for: a later timeout is armed again when it finds nothing due,
# and no delay can overflow rcl's signed 64-bit nanoseconds
_LONGEST_ARM_SEC = 3600.0

_of_node: 'weakref.WeakKeyDictionary[Node, Timeouts]' = weakref.WeakKeyDictionary()
_of_node_lock = threading.Lock()


class Timeouts:
    """Actions due after a delay, run by one timer of the node."""

    def __init__(self, node: Node) -> None:
        self._deadlines = Deadlines()
        self._keys = itertools.count()
        self._lock = threading.Lock()
        self._armed_at: float | None = None
        self._timer = node.create_timer(_LONGEST_ARM_SEC, self._on_timer)
        self._timer.cancel()

    def after(self, delay_sec: float, action: Callable[[], None]) -> Hashable:
        """Run `action` once `delay_sec` has passed, unless cancelled with the key returned."""
        key = next(self._keys)
        at = time.monotonic() + delay_sec
        with self._lock:
            self._deadlines.set(key, at, action)
            if self._armed_at is None or at < self._armed_at:
                self._arm()
        return key

    def cancel(self, key: Hashable) -> None:
        """Forget the action of `key` (nothing when it has run)."""
        with self._lock:
            self._deadlines.clear(key)

    def _arm(self) -> None:
        self._armed_at = self._deadlines.next_at()
        arm_for(self._timer, self._armed_at)

    def _on_timer(self) -> None:
        with self._lock:
            due = self._deadlines.pop_due(time.monotonic())
            self._arm()
        run_each(due)


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


def arm_for(timer: Timer, at: float | None) -> None:
    """Make `timer` fire once at `at` (time.monotonic()), or never for None: a timer that finds
    nothing due when it fires (at most an hour later) is armed again by its owner."""
    if at is None:
        timer.cancel()
        return
    delay_sec = at - time.monotonic()
    if not delay_sec < _LONGEST_ARM_SEC:  # NaN too
        delay_sec = _LONGEST_ARM_SEC
    timer.timer_period_ns = max(int(delay_sec * 1e9), 1)
    timer.reset()


def timeouts_of(node: Node) -> Timeouts:
    """The node's Timeouts, made on first use."""
    with _of_node_lock:
        timeouts = _of_node.get(node)
        if timeouts is None:
            timeouts = _of_node[node] = Timeouts(node)
        return timeouts
