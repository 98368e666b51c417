"""An Execution that runs on timers only: its feedback at start and each second, and an
optional deadline (system/wait, system/confirm); no thread sleeps, no polling."""

from typing import Any

from rclpy.node import Node
from rclpy.task import Future
from rclpy.timer import Timer

from task_manager.core.task import TaskEnd, TaskRecord
from task_manager.rclpy_tools.cleanup import destroy_timer

FEEDBACK_PERIOD_SEC = 1.0


class TimedExecution:
    """Records `feedback_at(elapsed_sec)` at start and each FEEDBACK_PERIOD_SEC; ends with
    `at_deadline()` after `deadline_sec` (None: no deadline), or earlier by `end`; it ends
    once, its timers gone. Subclasses give the feedback and how a cancel ends it."""

    def __init__(self, node: Node, record: TaskRecord, deadline_sec: float | None) -> None:
        self._node = node
        self._record = record
        self._started = node.get_clock().now()
        self.outcome: Future[TaskEnd] = Future()
        self._timers: list[Timer] = []
        # the deadline first: a period rcl refuses must not leave a feedback timer behind
        if deadline_sec is not None:
            self._timers.append(
                node.create_timer(deadline_sec, lambda: self.end(self.at_deadline()))
            )
        self._timers.append(node.create_timer(FEEDBACK_PERIOD_SEC, self._publish_feedback))
        self._publish_feedback()

    def feedback_at(self, elapsed_sec: float) -> dict[str, Any]:
        raise NotImplementedError

    def at_deadline(self) -> TaskEnd:
        raise NotImplementedError

    def _publish_feedback(self) -> None:
        elapsed_sec = (self._node.get_clock().now() - self._started).nanoseconds / 1e9
        self._record.record_feedback(self.feedback_at(elapsed_sec))

    def end(self, end: TaskEnd) -> None:
        for timer in self._timers:
            timer.cancel()
            destroy_timer(self._node, timer)
        self._timers.clear()
        if not self.outcome.done():
            self.outcome.set_result(end)
