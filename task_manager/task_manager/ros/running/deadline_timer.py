"""Every timeout and retry backoff of the node's tasks on one timer, armed for the earliest.

The deadlines themselves are kept in core/admission/deadlines.py (no rclpy); a queued or
running task costs no timer of its own.
"""

from collections.abc import Callable
from enum import StrEnum

from task_manager.rclpy_tools.timeouts import DeadlinesOnTimer


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


class DeadlineTimer(DeadlinesOnTimer):
    """Runs each task's deadline actions when due, from one rclpy timer of its own."""

    def set(
        self, task_id: str, what: Deadline, delay_sec: float, action: Callable[[], None]
    ) -> None:
        """Run `action` in `delay_sec`, unless this deadline of the task is cleared or set again."""
        self._set_deadline((task_id, what), delay_sec, action)

    def clear(self, task_id: str, *what: Deadline) -> None:
        """Forget these deadlines of the task (all of them when none is named)."""
        for deadline in what or tuple(Deadline):
            self._clear_deadline((task_id, deadline))
