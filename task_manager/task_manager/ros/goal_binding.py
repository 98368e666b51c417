"""Action goals served by the node, bound to the tasks they run."""

import contextlib
from typing import Any

from rclpy.action import CancelResponse

from task_manager.core.status import CancelReason, TaskStatus
from task_manager.core.task import TaskRecord, TaskRequest
from task_manager.ros.dispatcher import TaskDispatcher
from task_manager.ros.message_json import TaskDataError, message_from_dict


class GoalTaskBinding:
    """Runs an action goal's task and lets the goal's client cancel it."""

    def __init__(self, dispatcher: TaskDispatcher) -> None:
        self._dispatcher = dispatcher
        # key: goal id (bytes), value: the id of the task the goal runs
        self._task_ids_by_goal: dict[bytes, str] = {}

    async def run(
        self, goal_handle: Any, request: TaskRequest, feedback_type: Any = None
    ) -> TaskRecord:
        """Run the goal's task to its end and put the goal in the matching terminal state.

        With `feedback_type`, the task's feedback is forwarded to the goal's client.
        """
        goal_key = bytes(goal_handle.goal_id.uuid)

        def bind(record: TaskRecord) -> None:
            self._task_ids_by_goal[goal_key] = record.task_id
            if feedback_type is not None:
                record.feedback_listener = lambda feedback: _forward_feedback(
                    goal_handle, feedback_type, feedback
                )

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


def _forward_feedback(goal_handle: Any, feedback_type: Any, feedback: dict[str, Any]) -> None:
    if not goal_handle.is_active:
        return
    # feedback of another shape than the interface's has nothing to forward
    with contextlib.suppress(TaskDataError):
        goal_handle.publish_feedback(message_from_dict(feedback_type, feedback))


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
