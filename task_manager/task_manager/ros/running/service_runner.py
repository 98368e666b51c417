"""Running tasks on existing ROS 2 services."""

from collections.abc import Hashable
from typing import Any

from rclpy.client import Client
from rclpy.node import Node
from rclpy.task import Future

from task_manager.core.errors import TaskRequestError
from task_manager.core.status import ErrorCode, TaskStatus
from task_manager.core.task import TaskEnd, TaskRecord, status_for_service_response
from task_manager.core.task_spec import TaskSpec
from task_manager.messages.json_codec import message_from_json, message_to_dict
from task_manager.rclpy_tools.futures import wait_for, wait_until_ready
from task_manager.rclpy_tools.qos import DEEP_RELIABLE
from task_manager.rclpy_tools.request_window import RequestWindow
from task_manager.rclpy_tools.timeouts import timeouts_of
from task_manager.ros.running.execution import RunnerTimeouts, TaskRunner
from task_manager.ros.running.server_watch import ServerWatch, WatchSettings


class ServiceExecution:
    """A service call in flight. A service cannot be cancelled: cancel waits for the response.

    The call waits its turn in the runner's request window; `service_response_timeout` counts
    from when it left the window (the wait before is the node's, not the server's)."""

    def __init__(
        self,
        node: Node,
        window: RequestWindow,
        request: Any,
        spec: TaskSpec,
        response_timeout_sec: float,
    ) -> None:
        self._node = node
        self._window = window
        self._spec = spec
        self._response_timeout_sec = response_timeout_sec
        self._node_timeouts = timeouts_of(node)
        self._deadline: Hashable | None = None  # its key in the node's timeouts
        self.outcome: Future[Any] = Future()
        self._response_future = window.call_async(request)
        self._response_future.add_done_callback(self._on_response)
        window.sent(self._response_future).add_done_callback(self._arm_deadline)
        self.outcome.add_done_callback(lambda _: self._clean_up())

    def _arm_deadline(self, sent: Future[None]) -> None:
        if sent.cancelled() or self.outcome.done():
            return
        seconds = self._response_timeout_sec
        self._deadline = self._node_timeouts.after(
            seconds,
            lambda: self.fail(f'service {self._spec.topic} gave no response within {seconds} s'),
        )

    def _on_response(self, future: Future[Any]) -> None:
        if self.outcome.done() or future.cancelled() or future.result() is None:
            return
        response = message_to_dict(future.result())
        self.outcome.set_result(
            TaskEnd(status_for_service_response(response, self._spec), response)
        )

    def fail(self, reason: str) -> None:
        """End the task ERROR without waiting for a response any longer."""
        if not self.outcome.done():
            self.outcome.set_result(TaskEnd(TaskStatus.ERROR, {'error': reason}))

    def on_watch_tick(self, tick: int) -> int | None:
        """Nothing to ask again: a call cannot be repeated (its service may act twice)."""
        return None

    def _clean_up(self) -> None:
        if self._deadline is not None:
            self._node_timeouts.cancel(self._deadline)
        if not self._response_future.done():
            self._window.forget(self._response_future)

    async def cancel(self, timeout_sec: float) -> bool:
        return await wait_for(self._node, self.outcome, timeout_sec)


class ServiceTaskRunner(TaskRunner):
    """Calls one declared service task and watches the service while calls are in flight."""

    def __init__(
        self, node: Node, spec: TaskSpec, service_type: Any, timeouts: RunnerTimeouts
    ) -> None:
        self.spec = spec
        self._node = node
        self._service_type = service_type
        self._timeouts = timeouts
        # The message classes are untyped (no stubs for generated code), hence Any.
        self._client: Client[Any, Any] = node.create_client(
            service_type, spec.topic, qos_profile=DEEP_RELIABLE
        )
        # a server keeps its last 10 unread requests by default: a burst goes out 8 at a time;
        # a call unanswered for service_response_timeout gives its place up as it ends ERROR
        self._window = RequestWindow(
            node,
            self._client,
            timeouts.server_requests_in_flight,
            timeouts.service_response_sec,
        )
        self._watch = ServerWatch(
            node,
            self._client.service_is_ready,
            WatchSettings(timeouts.server_check_period_sec, timeouts.server_loss_timeout_sec),
            loss=f'service {spec.topic} left the ROS graph',
        )

    def parse(self, task_data: str, task_id: str) -> Any:
        return message_from_json(self._service_type.Request, task_data)

    async def start(self, message: Any, record: TaskRecord) -> ServiceExecution:
        if not await wait_until_ready(
            self._node, self._client.service_is_ready, self._timeouts.server_wait_sec
        ):
            raise TaskRequestError(
                ErrorCode.TASK_START_FAILED, f'service {self.spec.topic} is not available'
            )
        execution = ServiceExecution(
            self._node, self._window, message, self.spec, self._timeouts.service_response_sec
        )
        self._watch.track(execution)
        return execution
