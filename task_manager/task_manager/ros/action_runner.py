"""Running tasks on existing ROS 2 action servers."""

from typing import Any

from action_msgs.msg import GoalStatus
from action_msgs.srv import CancelGoal
from rclpy.action import ActionClient
from rclpy.node import Node
from rclpy.task import Future

from task_manager.core.errors import TaskRequestError
from task_manager.core.status import ErrorCode, ServerOutcome, TaskStatus
from task_manager.core.task import TaskEnd, TaskRecord, status_for_action_outcome
from task_manager.core.task_spec import TaskSpec
from task_manager.ros.execution import RunnerTimeouts
from task_manager.ros.futures import wait_for, wait_until_ready
from task_manager.ros.message_json import message_from_json, message_to_dict
from task_manager.ros.qos import DEEP_RELIABLE

# key: terminal GoalStatus value, value: how the server ended the goal
_OUTCOMES = {
    GoalStatus.STATUS_SUCCEEDED: ServerOutcome.SUCCEEDED,
    GoalStatus.STATUS_CANCELED: ServerOutcome.CANCELED,
    GoalStatus.STATUS_ABORTED: ServerOutcome.ABORTED,
}


def server_outcome(goal_status: int) -> ServerOutcome:
    """The one place GoalStatus becomes a ServerOutcome; anything unexpected is ABORTED."""
    return _OUTCOMES.get(goal_status, ServerOutcome.ABORTED)


class ActionExecution:
    """A goal accepted by a task's action server."""

    def __init__(self, node: Node, goal_handle: Any, spec: TaskSpec) -> None:
        self._node = node
        self._goal_handle = goal_handle
        self._spec = spec
        self.outcome: Future = Future()
        goal_handle.get_result_async().add_done_callback(self._on_result)

    def _on_result(self, future: Future) -> None:
        if self.outcome.done():
            return
        response = future.result()
        status = status_for_action_outcome(server_outcome(response.status), self._spec)
        self.outcome.set_result(TaskEnd(status, message_to_dict(response.result)))

    async def cancel(self, timeout_sec: float) -> bool:
        if self.outcome.done():
            return True
        started = self._node.get_clock().now()
        cancel_future = self._goal_handle.cancel_goal_async()
        if not await wait_for(self._node, cancel_future, timeout_sec):
            return self.outcome.done()
        if cancel_future.result().return_code == CancelGoal.Response.ERROR_REJECTED:
            return self.outcome.done()
        elapsed_sec = (self._node.get_clock().now() - started).nanoseconds / 1e9
        return await wait_for(self._node, self.outcome, timeout_sec - elapsed_sec)


class ActionTaskRunner:
    """Starts goals of one declared action task."""

    def __init__(
        self, node: Node, spec: TaskSpec, action_type: Any, timeouts: RunnerTimeouts
    ) -> None:
        self.spec = spec
        self._node = node
        self._action_type = action_type
        self._timeouts = timeouts
        self._client = ActionClient(
            node,
            action_type,
            spec.topic,
            goal_service_qos_profile=DEEP_RELIABLE,
            result_service_qos_profile=DEEP_RELIABLE,
            cancel_service_qos_profile=DEEP_RELIABLE,
            feedback_sub_qos_profile=DEEP_RELIABLE,
        )

    def parse(self, task_data: str) -> Any:
        return message_from_json(self._action_type.Goal, task_data)

    async def start(self, message: Any, record: TaskRecord) -> ActionExecution:
        topic = self.spec.topic
        if not await wait_until_ready(
            self._node, self._client.server_is_ready, self._timeouts.server_wait_sec
        ):
            raise TaskRequestError(
                ErrorCode.TASK_START_FAILED, f'action server {topic} is not available'
            )

        def on_feedback(feedback_message: Any) -> None:
            if record.status is TaskStatus.IN_PROGRESS:
                record.record_feedback(message_to_dict(feedback_message.feedback))

        goal_future = self._client.send_goal_async(message, feedback_callback=on_feedback)
        if not await wait_for(self._node, goal_future, self._timeouts.goal_response_sec):
            goal_future.add_done_callback(_cancel_late_goal)
            raise TaskRequestError(
                ErrorCode.TASK_START_FAILED,
                f'action server {topic} did not answer the goal within '
                f'{self._timeouts.goal_response_sec} s',
            )
        goal_handle = goal_future.result()
        if not goal_handle.accepted:
            raise TaskRequestError(
                ErrorCode.TASK_START_FAILED, f'action server {topic} rejected the goal'
            )
        return ActionExecution(self._node, goal_handle, self.spec)


def _cancel_late_goal(goal_future: Future) -> None:
    """A goal accepted after its start timed out would run untracked: cancel it."""
    goal_handle = goal_future.result()
    if goal_handle is not None and goal_handle.accepted:
        goal_handle.cancel_goal_async()
