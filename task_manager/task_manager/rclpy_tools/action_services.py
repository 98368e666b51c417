"""A client of an action server that speaks through the action's services and feedback topic.

rclpy's ActionClient keeps every pending future in a list that the executor walks on every
event, removes finished requests by a linear scan, and deserializes each status message,
which lists every goal the server keeps: its cost grows with the goals in flight. The
Task Manager needs no status messages (a goal's end comes with its result), so it sends
goals, asks for results and cancels on the action's three services, whose clients key
pending requests by sequence number, and reads feedback from the feedback topic.
"""

import uuid
from collections.abc import Callable
from typing import Any

from rclpy.client import Client
from rclpy.node import Node
from rclpy.subscription import Subscription
from rclpy.task import Future
from unique_identifier_msgs.msg import UUID

from task_manager.rclpy_tools.calls import call_async, forget
from task_manager.rclpy_tools.futures import completed_future
from task_manager.rclpy_tools.qos import DEEP_RELIABLE, RESULT_REPLIES
from task_manager.rclpy_tools.request_window import DEFAULT_SLOT_TIMEOUT_SEC, RequestWindow
from task_manager.rclpy_tools.server_wait import wait_until_ready

RESULT_SLOT_TIMEOUT_SEC = 0.5
"""An action server holds each GetResult request until its goal ends (rclpy's and rclcpp's do):
such requests are taken, not queued, and give their places up after this long unanswered, so
that goals that run for long do not hold every place. A result asked again that a busy server
drops is asked again at the next check."""


def action_service_name(action_name: str, service: str) -> str:
    """The name of one of an action's services: send_goal, get_result or cancel_goal."""
    return f'{action_name.rstrip("/")}/_action/{service}'


class ActionServicesClient:
    """Sends goals, gets results, cancels and receives feedback of one action server."""

    def __init__(
        self,
        node: Node,
        action_type: Any,
        action_name: str,
        requests_in_flight: int = 0,
        slot_timeout_sec: float = DEFAULT_SLOT_TIMEOUT_SEC,
    ) -> None:
        """`requests_in_flight` > 0: goals, cancels and results asked again are sent at most
        that many unanswered at a time per service (see request_window.py), for a server that
        keeps only a few unread requests, and places held by goals and cancels unanswered for
        `slot_timeout_sec` (none sent after them answered either) are given up; 0: each at
        once (a server with deep queues)."""
        impl = action_type.Impl
        self._impl = impl
        self._node = node
        # The message classes are untyped (no stubs for generated code), hence Any.
        self._send_goal: Client[Any, Any] = node.create_client(
            impl.SendGoalService,
            action_service_name(action_name, 'send_goal'),
            qos_profile=DEEP_RELIABLE,
        )
        self._get_result: Client[Any, Any] = node.create_client(
            impl.GetResultService,
            action_service_name(action_name, 'get_result'),
            qos_profile=RESULT_REPLIES,
        )
        self._cancel: Client[Any, Any] = node.create_client(
            impl.CancelGoalService,
            action_service_name(action_name, 'cancel_goal'),
            qos_profile=DEEP_RELIABLE,
        )
        self._windows: tuple[RequestWindow, RequestWindow, RequestWindow] | None = None
        if requests_in_flight > 0:
            self._windows = (
                RequestWindow(node, self._send_goal, requests_in_flight, slot_timeout_sec),
                RequestWindow(node, self._get_result, requests_in_flight, RESULT_SLOT_TIMEOUT_SEC),
                RequestWindow(node, self._cancel, requests_in_flight, slot_timeout_sec),
            )
        self._feedback_topic = f'{action_name.rstrip("/")}/_action/feedback'
        self._status_topic = f'{action_name.rstrip("/")}/_action/status'
        # key: goal id (bytes), value: called with each feedback message of that goal
        self._feedback_callbacks: dict[bytes, Callable[[Any], None]] = {}
        # made with the first feedback callback: a client that wants none (the Task Manager's
        # client of ExecuteTask) does not take every goal's feedback messages
        self._feedback: Subscription[Any] | None = None

    def server_ids(self) -> frozenset[bytes]:
        """The DDS ids of the action's servers now (of their status publishers, which every
        action server has): a server that restarted has new ones."""
        return frozenset(
            bytes(info.endpoint_gid)
            for info in self._node.get_publishers_info_by_topic(self._status_topic)
        )

    def server_is_ready(self) -> bool:
        return all(c.service_is_ready() for c in (self._send_goal, self._get_result, self._cancel))

    def wait_for_server(self, timeout_sec: float) -> bool:
        """Wait (bounded) until the server serves all three services; whether it does."""
        return wait_until_ready(self.server_is_ready, timeout_sec)

    def send_goal(
        self,
        goal: Any,
        goal_id: bytes | None = None,
        feedback_callback: Callable[[Any], None] | None = None,
    ) -> tuple[bytes, Future[Any]]:
        """Send a goal (with a new id, or `goal_id` to send one again); returns its id and a
        future of the SendGoal response (`accepted`)."""
        goal_id = goal_id or uuid.uuid4().bytes
        if feedback_callback is not None:
            self._feedback_callbacks[goal_id] = feedback_callback
            if self._feedback is None:
                self._feedback = self._node.create_subscription(
                    self._impl.FeedbackMessage,
                    self._feedback_topic,
                    self._on_feedback,
                    DEEP_RELIABLE,
                )
        request = self._impl.SendGoalService.Request(goal_id=_uuid(goal_id), goal=goal)
        if self._windows is not None:
            return goal_id, self._windows[0].call_async(request)
        return goal_id, call_async(self._send_goal, request)

    def get_result(self, goal_id: bytes, again: bool = False) -> Future[Any]:
        """A future of the GetResult response (`status`, `result`), once the goal has ended.

        `again`: the goal's result was asked for already and not answered (paced like a
        cancel: a round of asks again must not be a burst that a server drops)."""
        request = self._impl.GetResultService.Request(goal_id=_uuid(goal_id))
        if again and self._windows is not None:
            return self._windows[1].call_async(request)
        return call_async(self._get_result, request)

    def cancel(self, goal_id: bytes) -> Future[Any]:
        """A future of the CancelGoal response for one goal."""
        request = self._impl.CancelGoalService.Request()
        request.goal_info.goal_id = _uuid(goal_id)
        if self._windows is not None:
            return self._windows[2].call_async(request)
        return call_async(self._cancel, request)

    def goal_sent(self, future: Future[Any]) -> Future[None]:
        """A future done once a SendGoal request is sent to the server: at once, or once it
        has had its turn in the request window."""
        if self._windows is not None:
            return self._windows[0].sent(future)
        return completed_future()

    def forget_request(self, future: Future[Any]) -> None:
        """Stop waiting for the response to a SendGoal request (it was answered otherwise)."""
        if self._windows is not None:
            self._windows[0].forget(future)
        else:
            forget(self._send_goal, future)

    def forget_cancel_request(self, future: Future[Any]) -> None:
        """Stop waiting for the response to a CancelGoal request (it is sent again)."""
        if self._windows is not None:
            self._windows[2].forget(future)
        else:
            forget(self._cancel, future)

    def result_request_waits(self, future: Future[Any]) -> bool:
        """Whether a GetResult request asked again still waits its turn in the window."""
        return self._windows is not None and self._windows[1].waits(future)

    def forget_result_request(self, future: Future[Any]) -> None:
        """Stop waiting for the response to a GetResult request (asked again, or answered).

        The first ask goes to the client directly, asks again through the window: a window's
        request is forgotten there; an answered one is no longer pending anywhere."""
        if self._windows is not None and self._windows[1].holds(future):
            self._windows[1].forget(future)
        elif not future.done():
            forget(self._get_result, future)

    def forget(self, goal_id: bytes) -> None:
        """The goal has ended: drop its feedback callback."""
        self._feedback_callbacks.pop(goal_id, None)

    def _on_feedback(self, message: Any) -> None:
        callback = self._feedback_callbacks.get(bytes(message.goal_id.uuid))
        if callback is not None:
            callback(message.feedback)


def _uuid(goal_id: bytes) -> UUID:
    return UUID(uuid=list(goal_id))
