"""Every timeout and retry backoff of the node's tasks on one timer, armed for the earliest.

The deadlines themselves are kept in core/admission/deadlines.py (no rclpy); a queued or
running task costs no timer of its own.
"""

import time
from collections.abc import Callable
from enum import StrEnum

from rclpy.node import Node

from task_manager.core.admission.deadlines import Deadlines
from task_manager.rclpy_tools.timeouts import arm_for, run_each

_IDLE_PERIOD_SEC = 3600.0


class Deadline(StrEnum):
    """What a task's deadline ends: each task has at most one of each."""

    QUEUE = 'queue'
    """Its wait in the queue (queue_timeout_sec)."""
    RUN = 'run'
    """Its running attempt (timeout_sec)."""
    FEEDBACK = 'feedback'
    """Its running attempt's silence (feedback_timeout_sec)."""
    RETRY = 'retry'
    """The backoff before its next attempt."""


class DeadlineTimer:
    """Runs each task's deadline actions when due, from one rclpy timer."""

    def __init__(self, node: Node) -> None:
        self._deadlines = Deadlines()
        self._armed_at: float | None = None
        self._timer = node.create_timer(_IDLE_PERIOD_SEC, self._on_timer)
        self._timer.cancel()

    def set(
        self, task_id: str, what: Deadline, delay_sec: float, action: Callable[[], None]
    ) -> None:
        """Run `action` in `delay_sec`, unless this deadline of the task is cleared or set again."""
        at = time.monotonic() + delay_sec
        self._deadlines.set((task_id, what), at, action)
        if self._armed_at is None or at < self._armed_at:
            self._arm()

    def clear(self, task_id: str, *what: Deadline) -> None:
        """Forget these deadlines of the task (all of them when none is named)."""
        for deadline in what or tuple(Deadline):
            self._deadlines.clear((task_id, deadline))

    def _arm(self) -> None:
        self._armed_at = self._deadlines.next_at()
        arm_for(self._timer, self._armed_at)

    def _on_timer(self) -> None:
        due = self._deadlines.pop_due(time.monotonic())
        self._arm()  # first: an action that sets a deadline arms for it if it comes earlier
        run_each(due)
