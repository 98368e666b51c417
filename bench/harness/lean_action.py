"""Actions spoken through their own services, for a bench that measures the node and not rclpy.

An rclpy action server keeps every finished goal for `result_timeout` (10 s by default) and
lists all the goals it keeps in each status message, which every rclpy ActionClient
deserializes in Python. At the hundreds of goals per second of a benchmark (never on a robot)
that grows to milliseconds per goal, on both sides of the comparison. So:
- the bench's clients send goals and ask for results on the action's services, as rclpy's
  ActionClient does, without subscribing to status and feedback;
- the instant server answers on those services and keeps each result for RESULT_KEEP_SEC
  (rclpy's default result_timeout), asked for or not: the node asks again for a result whose
  answer is late, and a server that forgot it once asked would answer "unknown goal"; it
  publishes one status message per goal, listing that goal alone, as a server with few
  goals would.
"""

import time
import uuid
from typing import Any

from action_msgs.msg import GoalInfo, GoalStatus, GoalStatusArray
from action_msgs.srv import CancelGoal
from rclpy.client import Client
from rclpy.node import Node
from rclpy.qos import qos_profile_action_status_default
from rclpy.task import Future
from unique_identifier_msgs.msg import UUID

from bench.harness.replies import Reply, stamped
from task_manager.rclpy_tools.futures import result_of
from task_manager.rclpy_tools.qos import DEEP_RELIABLE

FEEDBACK_DEPTH = 10


def action_service(action_name: str, service: str) -> str:
    """The name of one of an action's services: send_goal, get_result or cancel_goal."""
    return f'{action_name}/_action/{service}'


class LeanActionClient:
    """Sends goals and gets their results through the action's goal and result services."""

    def __init__(self, node: Node, action_type: Any, action_name: str) -> None:
        self.action_name = action_name
        self._node = node
        self._impl = action_type.Impl
        # The message classes are untyped (no stubs for generated code), hence Any.
        self._send_goal: Client[Any, Any] = node.create_client(
            self._impl.SendGoalService,
            action_service(action_name, 'send_goal'),
            qos_profile=DEEP_RELIABLE,
        )
        self._get_result: Client[Any, Any] = node.create_client(
            self._impl.GetResultService,
            action_service(action_name, 'get_result'),
            qos_profile=DEEP_RELIABLE,
        )

    def wait_for_server(self, timeout_sec: float) -> bool:
        return self._send_goal.wait_for_service(timeout_sec) and self._get_result.wait_for_service(
            timeout_sec
        )

    def send_goal(self, goal: Any, accepted: Future[Any] | None = None) -> Future[Any]:
        """A future completing with the Reply of the goal's result (response None if rejected).

        The response has `status` (GoalStatus) and `result`, like rclpy's get_result_async.
        `accepted`, if given, completes with a Reply whose response is whether the server
        accepted the goal.
        """
        goal_id = UUID(uuid=list(uuid.uuid4().bytes))
        replied: Future[Any] = Future()

        def on_goal_response(future: Future[Any]) -> None:
            is_accepted = bool(result_of(future).accepted)
            if accepted is not None:
                accepted.set_result(Reply(time.perf_counter(), is_accepted))
            if not is_accepted:
                replied.set_result(Reply(time.perf_counter(), None))
                return
            request = self._impl.GetResultService.Request(goal_id=goal_id)
            self._get_result.call_async(request).add_done_callback(stamped(replied))

        request = self._impl.SendGoalService.Request(goal_id=goal_id, goal=goal)
        self._send_goal.call_async(request).add_done_callback(on_goal_response)
        return replied

    def destroy(self) -> None:
        self._node.destroy_client(self._send_goal)
        self._node.destroy_client(self._get_result)


RESULT_KEEP_SEC = 10.0


class InstantActionServer:
    """Accepts every goal and ends it at once with `finish(goal)` as its result."""

    def __init__(
        self, node: Node, action_type: Any, action_name: str, finish: Any, group: Any
    ) -> None:
        self._node = node
        self._impl = action_type.Impl
        self._finish = finish
        # key: goal id (bytes), value: (when it ended, its result), oldest first
        self._results: dict[bytes, tuple[float, Any]] = {}
        for service, service_type, callback in (
            ('send_goal', self._impl.SendGoalService, self._on_goal),
            ('get_result', self._impl.GetResultService, self._on_get_result),
            ('cancel_goal', self._impl.CancelGoalService, self._on_cancel),
        ):
            node.create_service(
                service_type,
                action_service(action_name, service),
                callback,
                qos_profile=DEEP_RELIABLE,
                callback_group=group,
            )
        # clients take an action server as available only once both topics have a publisher
        node.create_publisher(
            self._impl.FeedbackMessage, f'{action_name}/_action/feedback', FEEDBACK_DEPTH
        )
        self._status = node.create_publisher(
            self._impl.GoalStatusMessage,
            f'{action_name}/_action/status',
            qos_profile_action_status_default,
        )

    def _on_goal(self, request: Any, response: Any) -> Any:
        now = time.monotonic()
        while self._results:  # the oldest first, as dicts keep their order
            oldest = next(iter(self._results))
            if now - self._results[oldest][0] < RESULT_KEEP_SEC:
                break
            del self._results[oldest]
        self._results[bytes(request.goal_id.uuid)] = (now, self._finish(request.goal))
        response.accepted = True
        response.stamp = self._node.get_clock().now().to_msg()
        info = GoalInfo(goal_id=request.goal_id, stamp=response.stamp)
        self._status.publish(
            GoalStatusArray(
                status_list=[GoalStatus(goal_info=info, status=GoalStatus.STATUS_SUCCEEDED)]
            )
        )
        return response

    def _on_get_result(self, request: Any, response: Any) -> Any:
        kept = self._results.get(bytes(request.goal_id.uuid))
        if kept is None:
            response.status = GoalStatus.STATUS_UNKNOWN
            return response
        response.status = GoalStatus.STATUS_SUCCEEDED
        response.result = kept[1]
        return response

    def _on_cancel(self, _request: Any, response: Any) -> Any:
        response.return_code = CancelGoal.Response.ERROR_REJECTED
        return response
