"""system/wait: wait a given time, or until cancelled; timers only, no thread sleeps."""

from typing import Any

from rclpy.node import Node
from rclpy.task import Future
from task_manager_msgs.action import Wait

from task_manager.core.status import TaskStatus
from task_manager.core.system_tasks import WAIT_SPEC
from task_manager.core.task import TaskEnd, TaskRecord
from task_manager.rclpy_tools.cleanup import destroy_timer
from task_manager.ros.message_json import message_from_json

FEEDBACK_PERIOD_SEC = 1.0
UNTIL_CANCELLED = -1.0
"""remaining_time reported by a wait without an end (duration <= 0)."""


class WaitExecution:
    """A running wait. With duration <= 0, the cancel is the signal to go on: it ends DONE."""

    def __init__(self, node: Node, duration_sec: float, record: TaskRecord) -> None:
        self._node = node
        self._record = record
        self._duration_sec = duration_sec
        self._started = node.get_clock().now()
        self.outcome: Future = Future()
        self._timers = [node.create_timer(FEEDBACK_PERIOD_SEC, self._publish_feedback)]
        if duration_sec > 0:
            self._timers.append(node.create_timer(duration_sec, lambda: self._end(TaskStatus.DONE)))
        self._publish_feedback()

    @property
    def _is_endless(self) -> bool:
        return self._duration_sec <= 0

    def _remaining_sec(self) -> float:
        if self._is_endless:
            return UNTIL_CANCELLED
        elapsed_sec = (self._node.get_clock().now() - self._started).nanoseconds / 1e9
        return max(0.0, self._duration_sec - elapsed_sec)

    def _publish_feedback(self) -> None:
        self._record.record_feedback({'remaining_time': self._remaining_sec()})

    def _end(self, status: TaskStatus) -> None:
        for timer in self._timers:
            timer.cancel()
            destroy_timer(self._node, timer)
        self._timers.clear()
        if not self.outcome.done():
            self.outcome.set_result(TaskEnd(status, {}))

    async def cancel(self, timeout_sec: float) -> bool:
        self._end(TaskStatus.DONE if self._is_endless else TaskStatus.CANCELED)
        return True


class WaitRunner:
    """Starts waits; blocking and cancel_on_stop, like a task that holds the robot."""

    spec = WAIT_SPEC

    def __init__(self, node: Node) -> None:
        self._node = node

    def parse(self, task_data: str, task_id: str) -> Any:
        return message_from_json(Wait.Goal, task_data)

    async def start(self, message: Any, record: TaskRecord) -> WaitExecution:
        return WaitExecution(self._node, float(message.duration), record)
