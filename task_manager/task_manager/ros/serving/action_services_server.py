"""An action server that serves an action through its own services and topics.

rclpy's ActionServer walks every future it holds on each event, formats goal ids into debug
strings that are never printed, and goes through the executor's waitable machinery for each
request: at the rate of a Task Manager's ExecuteTask that was a fifth of the node's time
(docs/benchmarks.md). This server speaks the same protocol on the same names and types:
- `<action>/_action/send_goal`: a goal with a known id is rejected, any other accepted and
  stamped; it goes ACCEPTED -> EXECUTING and its execute coroutine starts;
- `<action>/_action/get_result`: answered when the goal ends (at once if it has), status
  UNKNOWN for an id it does not know (or no longer keeps);
- `<action>/_action/cancel_goal`: the goal-id / stamp rules of action_msgs/srv/CancelGoal,
  return codes included; each goal to cancel is offered to the cancel callback;
- `<action>/_action/status`: the status of every goal it keeps (transient local, depth 1),
  published once per executor turn with changes, and at most STATUS_RATE_HZ a second when it
  lists more than LARGE_STATUS goals (the topic keeps only the latest anyway); sent as bytes
  joined from each goal's part (goal_status_wire.py), not converted field by field;
- `<action>/_action/feedback`.
A finished goal is kept for `result_timeout_sec` (10 s, as rclpy), then forgotten: one timer
serves all of them.
"""

import time
from collections import deque
from collections.abc import Callable, Coroutine
from typing import Any

from action_msgs.msg import GoalInfo, GoalStatus, GoalStatusArray
from action_msgs.srv import CancelGoal
from rclpy.action.server import CancelResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.qos import QoSProfile, qos_profile_action_status_default
from rclpy.task import Future
from rclpy.timer import Timer

from task_manager.rclpy_tools.action_services import action_service_name
from task_manager.rclpy_tools.cleanup import destroy_timer
from task_manager.rclpy_tools.futures import resolved
from task_manager.rclpy_tools.log import NodeLog
from task_manager.rclpy_tools.qos import DEEP_RELIABLE, without_qos_events
from task_manager.ros.recording.turn_publication import TurnPublication
from task_manager.ros.serving.goal_status_wire import (
    StatusArrayEncoding,
    part_of,
    status_array_encoding,
)

RESULT_TIMEOUT_SEC = 10.0
LARGE_STATUS = 100
STATUS_RATE_HZ = 10.0
FEEDBACK_QOS = QoSProfile(depth=10)

_ACTIVE = (GoalStatus.STATUS_ACCEPTED, GoalStatus.STATUS_EXECUTING, GoalStatus.STATUS_CANCELING)
# key: status, value: the statuses a goal may move to from it (rcl_action's state machine)
_TRANSITIONS = {
    GoalStatus.STATUS_ACCEPTED: (GoalStatus.STATUS_EXECUTING, GoalStatus.STATUS_CANCELING),
    GoalStatus.STATUS_EXECUTING: (
        GoalStatus.STATUS_CANCELING,
        GoalStatus.STATUS_SUCCEEDED,
        GoalStatus.STATUS_ABORTED,
    ),
    GoalStatus.STATUS_CANCELING: (
        GoalStatus.STATUS_SUCCEEDED,
        GoalStatus.STATUS_ABORTED,
        GoalStatus.STATUS_CANCELED,
    ),
}


class ServedGoal:
    """One goal: what an execute callback gets (the parts of rclpy's ServerGoalHandle used)."""

    def __init__(self, server: 'ActionServicesServer', request: Any, stamp: Any) -> None:
        self._server = server
        self.goal_id = request.goal_id
        self.request = request.goal
        self.status_msg = GoalStatus(
            goal_info=GoalInfo(goal_id=request.goal_id, stamp=stamp),
            status=GoalStatus.STATUS_ACCEPTED,
        )
        self.status_part = part_of(self.status_msg)
        """Its part of the status array, as the middleware sends it (goal_status_wire.py)."""
        self.result: Future[Any] = Future()
        """Completes with the GetResult response once the goal has ended."""

    @property
    def key(self) -> bytes:
        return bytes(self.goal_id.uuid)

    @property
    def status(self) -> int:
        return int(self.status_msg.status)

    @property
    def is_active(self) -> bool:
        return self.status in _ACTIVE

    @property
    def is_cancel_requested(self) -> bool:
        return bool(self.status == GoalStatus.STATUS_CANCELING)

    def succeed(self) -> None:
        self._move_to(GoalStatus.STATUS_SUCCEEDED)

    def abort(self) -> None:
        self._move_to(GoalStatus.STATUS_ABORTED)

    def canceled(self) -> None:
        self._move_to(GoalStatus.STATUS_CANCELED)

    def publish_feedback(self, feedback: Any) -> None:
        self._server.publish_feedback(self, feedback)

    def _move_to(self, status: int) -> None:
        if status not in _TRANSITIONS.get(self.status, ()):
            raise RuntimeError(f'goal cannot go from status {self.status} to {status}')
        self.status_msg.status = status
        self.status_part = StatusArrayEncoding.with_status(self.status_part, status)
        self._server.status_changed()


ExecuteCallback = Callable[[ServedGoal], Coroutine[Any, Any, Any]]
CancelCallback = Callable[[ServedGoal], CancelResponse]


class ActionServicesServer:
    """Serves one action (see the module doc); goals are always accepted."""

    def __init__(
        self,
        node: Node,
        action_type: Any,
        action_name: str,
        execute: ExecuteCallback,
        cancel: CancelCallback,
        result_timeout_sec: float = RESULT_TIMEOUT_SEC,
    ) -> None:
        self._node = node
        self._impl = action_type.Impl
        self._result_type = action_type.Result
        self._execute = execute
        self._cancel = cancel
        self._result_timeout_sec = result_timeout_sec
        self._log = NodeLog.of(node, 'execute_task')
        group = ReentrantCallbackGroup()  # get_result answers wait: they must not hold a group
        handlers: list[tuple[Any, str, Callable[[Any, Any], Any]]] = [
            (self._impl.SendGoalService, 'send_goal', self._on_goal),
            (self._impl.GetResultService, 'get_result', self._on_get_result),
            (self._impl.CancelGoalService, 'cancel_goal', self._on_cancel),
        ]
        self._services = [
            node.create_service(
                service_type,
                action_service_name(action_name, service),
                handler,
                qos_profile=DEEP_RELIABLE,
                callback_group=group,
            )
            for service_type, service, handler in handlers
        ]
        name = action_name.rstrip('/')
        self._feedback = node.create_publisher(
            self._impl.FeedbackMessage,
            f'{name}/_action/feedback',
            FEEDBACK_QOS,
            event_callbacks=without_qos_events(),
        )
        self._status = node.create_publisher(
            GoalStatusArray,
            f'{name}/_action/status',
            qos_profile_action_status_default,
            event_callbacks=without_qos_events(),
        )
        self._status_encoding = status_array_encoding()
        # key: goal id (bytes), value: the goal, from acceptance until it expires
        self._goals: dict[bytes, ServedGoal] = {}
        # (when it expires, goal id) of ended goals, oldest first
        self._expiries: deque[tuple[float, bytes]] = deque()
        self._expiry_timer: Timer | None = None
        self._status_publication = TurnPublication(
            node,
            self._publish_status,
            lambda: len(self._goals) > LARGE_STATUS,
            STATUS_RATE_HZ,
        )

    # ---- the three services ------------------------------------------------------------------

    def _on_goal(self, request: Any, response: Any) -> Any:
        key = bytes(request.goal_id.uuid)
        if key in self._goals:  # a goal id is used once (rclpy rejects it too)
            response.accepted = False
            return response
        stamp = self._node.get_clock().now().to_msg()
        goal = ServedGoal(self, request, stamp)
        self._goals[key] = goal
        response.accepted = True
        response.stamp = stamp
        self.status_changed()
        self._spawn(self._run(goal))  # after this answer has gone out
        return response

    async def _run(self, goal: ServedGoal) -> None:
        if goal.status == GoalStatus.STATUS_ACCEPTED:  # not when cancelled since its acceptance
            goal._move_to(GoalStatus.STATUS_EXECUTING)
        try:
            result = await self._execute(goal)
        except Exception as error:  # the callback boundary: the goal still gets its answer
            self._log.error(f'execute callback failed: {error!r}')
            result = self._result_type()
        if goal.is_active:
            goal.abort()
        goal.result.set_result(
            self._impl.GetResultService.Response(status=goal.status, result=result)
        )
        self._expire_later(goal.key)

    async def _on_get_result(self, request: Any, response: Any) -> Any:
        goal = self._goals.get(bytes(request.goal_id.uuid))
        if goal is None:
            response.status = GoalStatus.STATUS_UNKNOWN
            return response
        return await resolved(self._node, goal.result)

    def _on_cancel(self, request: CancelGoal.Request, response: CancelGoal.Response) -> Any:
        code, goals = self._goals_to_cancel(request.goal_info)
        response.return_code = code
        for goal in goals:
            if self._cancel(goal) is CancelResponse.ACCEPT and goal.is_active:
                goal._move_to(GoalStatus.STATUS_CANCELING)
                response.goals_canceling.append(goal.status_msg.goal_info)
        return response

    def _goals_to_cancel(self, info: GoalInfo) -> tuple[int, list[ServedGoal]]:
        """CancelGoal's rules: a zero id and zero stamp cancel every goal; a stamp, every goal
        accepted at or before it; an id, that goal (with a stamp: and those before it)."""
        key = bytes(info.goal_id.uuid)
        by_id = any(key)
        before_ns = info.stamp.sec * 1_000_000_000 + info.stamp.nanosec
        chosen: list[ServedGoal] = []
        if by_id:
            goal = self._goals.get(key)
            if goal is None:
                return CancelGoal.Response.ERROR_UNKNOWN_GOAL_ID, []
            if not goal.is_active:
                return CancelGoal.Response.ERROR_GOAL_TERMINATED, []
            chosen.append(goal)
        if not by_id or before_ns:
            chosen += [
                goal
                for goal in self._goals.values()
                if goal.is_active
                and goal not in chosen
                and (not before_ns or _stamp_ns(goal) <= before_ns)
            ]
        if not chosen:
            return CancelGoal.Response.ERROR_REJECTED, []
        return CancelGoal.Response.ERROR_NONE, chosen

    # ---- topics ---------------------------------------------------------------------------------

    def publish_feedback(self, goal: ServedGoal, feedback: Any) -> None:
        self._feedback.publish(self._impl.FeedbackMessage(goal_id=goal.goal_id, feedback=feedback))

    def status_changed(self) -> None:
        """Publish the status array after this executor turn (bounded when it is large)."""
        self._status_publication.changed()

    def _publish_status(self) -> None:
        if self._status_encoding is not None:
            self._status.publish(
                self._status_encoding.array([goal.status_part for goal in self._goals.values()])
            )
        else:
            statuses = [goal.status_msg for goal in self._goals.values()]
            self._status.publish(GoalStatusArray(status_list=statuses))

    # ---- expiry ---------------------------------------------------------------------------------

    def _expire_later(self, key: bytes) -> None:
        self._expiries.append((time.monotonic() + self._result_timeout_sec, key))
        if self._expiry_timer is None:
            self._arm_expiry()

    def _arm_expiry(self) -> None:
        wait_sec = max(self._expiries[0][0] - time.monotonic(), 0.001)
        self._expiry_timer = self._node.create_timer(wait_sec, self._expire)

    def _expire(self) -> None:
        if self._expiry_timer is not None:
            destroy_timer(self._node, self._expiry_timer)
            self._expiry_timer = None
        now = time.monotonic()
        expired = False
        while self._expiries and self._expiries[0][0] <= now:
            self._goals.pop(self._expiries.popleft()[1], None)
            expired = True
        if expired:
            self.status_changed()
        if self._expiries:
            self._arm_expiry()

    def _spawn(self, coroutine: Coroutine[Any, Any, Any]) -> None:
        assert self._node.executor is not None, 'the node must be added to an executor'
        # rclpy runs coroutines too, but types create_task for callables only
        self._node.executor.create_task(coroutine)  # type: ignore[call-overload]


def _stamp_ns(goal: ServedGoal) -> int:
    stamp = goal.status_msg.goal_info.stamp
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)
