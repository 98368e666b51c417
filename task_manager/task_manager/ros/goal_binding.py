"""Action goals served by the node, bound to the tasks they run."""

from collections.abc import Callable
from typing import Any

from rclpy.action import CancelResponse

from task_manager.core.status import CancelReason, TaskStatus
from task_manager.core.task import TaskRecord, TaskRequest
from task_manager.ros.dispatcher import TaskDispatcher


class GoalTaskBinding:
    """Runs an action goal's task and lets the goal's client cancel it."""

    def __init__(self, dispatcher: TaskDispatcher) -> None:
        self._dispatcher = dispatcher
        # key: goal id (bytes), value: the id of the task the goal runs
        self._task_ids_by_goal: dict[bytes, str] = {}

    async def run(self, goal_handle: Any, request: TaskRequest) -> TaskRecord:
        """Run the goal's task to its end and put the goal in the matching terminal state."""
        goal_key = bytes(goal_handle.goal_id.uuid)

        def bind(record: TaskRecord) -> None:
            self._task_ids_by_goal[goal_key] = record.task_id

        record = await self._dispatcher.run(request, on_admitted=bind)
        self._task_ids_by_goal.pop(goal_key, None)
        finish_goal(goal_handle, record)
        return record

    def cancel_callback(self, goal_handle: Any) -> CancelResponse:
        """Accept a client's cancel and start cancelling the goal's task."""
        task_id = self._task_ids_by_goal.get(bytes(goal_handle.goal_id.uuid))
        if task_id is None:
            return CancelResponse.REJECT
        self._dispatcher.cancel(task_id, CancelReason.CLIENT)
        return CancelResponse.ACCEPT


def finish_goal(goal_handle: Any, record: TaskRecord) -> None:
    """DONE succeeds; CANCELED at the client's request is canceled; the rest is aborted.

    ROS allows "canceled" only for a goal whose client asked for it, so a task cancelled by
    someone else (a conflict, system/cancel_task, system/stop) aborts its goal.
    """
    if record.status is TaskStatus.DONE:
        goal_handle.succeed()
    elif record.status is TaskStatus.CANCELED and goal_handle.is_cancel_requested:
        goal_handle.canceled()
    else:
        goal_handle.abort()


OnAdmitted = Callable[[TaskRecord], None]
