"""Running tasks on existing ROS 2 action servers."""

import uuid
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
from task_manager.ros.server_watch import ServerWatch, WatchSettings

# key: terminal GoalStatus value, value: how the server ended the goal
_OUTCOMES = {
    GoalStatus.STATUS_SUCCEEDED: ServerOutcome.SUCCEEDED,
    GoalStatus.STATUS_CANCELED: ServerOutcome.CANCELED,
    GoalStatus.STATUS_ABORTED: ServerOutcome.ABORTED,
}
# How long a result may be missing after the server reported the goal ended, before it is
# asked for again (a reply can be lost on the network).
RESULT_RETRY_SEC = 2.0


def server_outcome(goal_status: int) -> ServerOutcome:
    """The one place GoalStatus becomes a ServerOutcome; anything unexpected is ABORTED."""
    return _OUTCOMES.get(goal_status, ServerOutcome.ABORTED)


class ActionExecution:
    """A goal accepted by a task's action server."""

    def __init__(self, node: Node, goal_handle: Any, spec: TaskSpec) -> None:
        self._node = node
        self._goal_handle = goal_handle
        self._spec = spec
        self._ended_unseen_since_ns: int | None = None
        self.outcome: Future = Future()
        goal_handle.get_result_async().add_done_callback(self._on_result)

    def _on_result(self, future: Future) -> None:
        response = future.result()
        if self.outcome.done() or response is None:
            return
        status = status_for_action_outcome(server_outcome(response.status), self._spec)
        self.outcome.set_result(TaskEnd(status, message_to_dict(response.result)))

    def fail(self, reason: str) -> None:
        """End the task ERROR without its server (e.g. the server is gone)."""
        if not self.outcome.done():
            self.outcome.set_result(TaskEnd(TaskStatus.ERROR, {'error': reason}))

    def check_result_delivery(self) -> None:
        """Ask again for a result the server has reported as ready but that never arrived."""
        if self.outcome.done() or self._goal_handle.status not in _OUTCOMES:
            return
        now_ns = self._node.get_clock().now().nanoseconds
        if self._ended_unseen_since_ns is None:
            self._ended_unseen_since_ns = now_ns
        elif (now_ns - self._ended_unseen_since_ns) / 1e9 > RESULT_RETRY_SEC:
            self._ended_unseen_since_ns = now_ns
            self._goal_handle.get_result_async().add_done_callback(self._on_result)

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
    """Starts goals of one declared action task and watches its server while they run."""

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
        # Liveness probe: a cancel request for a goal id that does not exist is answered at
        # once by a live server and cancels nothing.
        self._probe_client = node.create_client(
            CancelGoal, f'{spec.topic.rstrip("/")}/_action/cancel_goal'
        )
        self._in_flight: set[ActionExecution] = set()
        self._watch = ServerWatch(
            node,
            self._probe,
            WatchSettings(timeouts.server_check_period_sec, timeouts.server_loss_timeout_sec),
            on_lost=self._server_lost,
            on_tick=self._check_results,
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
            self._watch.mark_alive()
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
        return self._track(ActionExecution(self._node, goal_handle, self.spec))

    def _track(self, execution: ActionExecution) -> ActionExecution:
        self._in_flight.add(execution)
        self._watch.watch()

        def forget(_: Future) -> None:
            self._in_flight.discard(execution)
            self._watch.unwatch()

        execution.outcome.add_done_callback(forget)
        return execution

    def _probe(self) -> bool | Future:
        if not self._client.server_is_ready():
            return False
        request = CancelGoal.Request()
        request.goal_info.goal_id.uuid = list(uuid.uuid4().bytes)
        return self._probe_client.call_async(request)

    def _check_results(self) -> None:
        for execution in list(self._in_flight):
            execution.check_result_delivery()

    def _server_lost(self) -> None:
        reason = (
            f'action server {self.spec.topic} stopped answering for more than '
            f'{self._timeouts.server_loss_timeout_sec} s'
        )
        self._node.get_logger().error(f'{reason}; failing its {len(self._in_flight)} task(s)')
        for execution in list(self._in_flight):
            execution.fail(reason)


def _cancel_late_goal(goal_future: Future) -> None:
    """A goal accepted after its start timed out would run untracked: cancel it."""
    goal_handle = goal_future.result()
    if goal_handle is not None and goal_handle.accepted:
        goal_handle.cancel_goal_async()
