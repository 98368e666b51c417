"""Running tasks on existing ROS 2 services."""

from typing import Any

from rclpy.node import Node
from rclpy.task import Future

from task_manager.core.errors import TaskRequestError
from task_manager.core.status import ErrorCode
from task_manager.core.task import TaskEnd, TaskRecord, status_for_service_response
from task_manager.core.task_spec import TaskSpec
from task_manager.ros.execution import RunnerTimeouts
from task_manager.ros.futures import wait_for, wait_until_ready
from task_manager.ros.message_json import message_from_json, message_to_dict
from task_manager.ros.qos import DEEP_RELIABLE


class ServiceExecution:
    """A service call in flight. A service cannot be cancelled: cancel waits for the response."""

    def __init__(self, node: Node, response_future: Future, spec: TaskSpec) -> None:
        self._node = node
        self._spec = spec
        self.outcome: Future = Future()
        response_future.add_done_callback(self._on_response)

    def _on_response(self, future: Future) -> None:
        if self.outcome.done() or future.cancelled():
            return
        response = message_to_dict(future.result())
        self.outcome.set_result(
            TaskEnd(status_for_service_response(response, self._spec), response)
        )

    async def cancel(self, timeout_sec: float) -> bool:
        return await wait_for(self._node, self.outcome, timeout_sec)


class ServiceTaskRunner:
    """Calls one declared service task."""

    def __init__(
        self, node: Node, spec: TaskSpec, service_type: Any, timeouts: RunnerTimeouts
    ) -> None:
        self.spec = spec
        self._node = node
        self._service_type = service_type
        self._timeouts = timeouts
        self._client = node.create_client(service_type, spec.topic, qos_profile=DEEP_RELIABLE)

    def parse(self, task_data: str) -> Any:
        return message_from_json(self._service_type.Request, task_data)

    async def start(self, message: Any, record: TaskRecord) -> ServiceExecution:
        if not await wait_until_ready(
            self._node, self._client.service_is_ready, self._timeouts.server_wait_sec
        ):
            raise TaskRequestError(
                ErrorCode.TASK_START_FAILED, f'service {self.spec.topic} is not available'
            )
        return ServiceExecution(self._node, self._client.call_async(message), self.spec)
