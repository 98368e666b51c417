"""system/wait: wait a given time, or until cancelled; timers only, no thread sleeps."""

from typing import Any

from rclpy.node import Node
from task_manager_msgs.action import Wait

from task_manager.core.bounds import SECONDS
from task_manager.core.status import TaskStatus
from task_manager.core.system_tasks import WAIT_SPEC
from task_manager.core.task import TaskEnd, TaskRecord
from task_manager.messages.json_codec import TaskDataError, message_from_json
from task_manager.ros.running.execution import TaskRunner
from task_manager.ros.system.timed_execution import TimedExecution

UNTIL_CANCELLED = -1.0
"""remaining_time reported by a wait without an end (duration <= 0)."""


class WaitExecution(TimedExecution):
    """A running wait. With duration <= 0, the cancel is the signal to go on: it ends DONE."""

    def __init__(self, node: Node, duration_sec: float, record: TaskRecord) -> None:
        self._duration_sec = duration_sec
        super().__init__(node, record, None if self._is_endless else duration_sec)

    @property
    def _is_endless(self) -> bool:
        return self._duration_sec <= 0

    def feedback_at(self, elapsed_sec: float) -> dict[str, Any]:
        if self._is_endless:
            return {'remaining_time': UNTIL_CANCELLED}
        return {'remaining_time': max(0.0, self._duration_sec - elapsed_sec)}

    def at_deadline(self) -> TaskEnd:
        return TaskEnd(TaskStatus.DONE, {})

    async def cancel(self, timeout_sec: float) -> bool:
        self.end(TaskEnd(TaskStatus.DONE if self._is_endless else TaskStatus.CANCELED, {}))
        return True


class WaitRunner(TaskRunner):
    """Starts waits; blocking and cancel_on_stop, like a task that holds the robot."""

    spec = WAIT_SPEC

    def __init__(self, node: Node) -> None:
        self._node = node

    def parse(self, task_data: str, task_id: str) -> Any:
        goal = message_from_json(Wait.Goal, task_data)
        if goal.duration > 0 and (problem := SECONDS.problem('duration', goal.duration)):
            raise TaskDataError('duration', f'{problem} (<= 0: until cancelled)')
        return goal

    async def start(self, message: Any, record: TaskRecord) -> WaitExecution:
        return WaitExecution(self._node, float(message.duration), record)
