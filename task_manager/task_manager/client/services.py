"""How the client's parts reach the Task Manager: a call of one of its services that only
read (or, as confirm_task, take a request asked again as the first), asked again when a reply
is lost, and what every part of the client stands on (`ClientParts`)."""

import threading
import time
from collections.abc import Collection, Sequence
from typing import Any

from rcl_interfaces.srv import GetParameters, ListParameters
from rclpy.client import Client
from rclpy.task import Future
from task_manager_msgs.srv import (
    ConfirmTask,
    GetSchedules,
    GetTaskResults,
    GetTaskStates,
    QueryTaskHistory,
)

from task_manager.client.connection import SERVICE_RETRY_SEC, Connection
from task_manager.client.records import TaskResult
from task_manager.core.bounds import check_wait_seconds
from task_manager.core.errors import TaskManagerUnavailable
from task_manager.core.names import (
    CONFIRM_TASK_SERVICE,
    GET_PARAMETERS_SERVICE,
    GET_SCHEDULES_SERVICE,
    GET_TASK_RESULTS_SERVICE,
    GET_TASK_STATES_SERVICE,
    IDS_MAX,
    LIST_PARAMETERS_SERVICE,
    QUERY_TASK_HISTORY_SERVICE,
)
from task_manager.rclpy_tools.server_wait import wait_until_ready

SERVICE_TYPES: dict[str, Any] = {
    GET_TASK_STATES_SERVICE: GetTaskStates,
    GET_TASK_RESULTS_SERVICE: GetTaskResults,
    QUERY_TASK_HISTORY_SERVICE: QueryTaskHistory,
    GET_SCHEDULES_SERVICE: GetSchedules,
    CONFIRM_TASK_SERVICE: ConfirmTask,
    LIST_PARAMETERS_SERVICE: ListParameters,
    GET_PARAMETERS_SERVICE: GetParameters,
}
"""key: a service of the Task Manager that the client calls, value: its type."""


def id_asks(ids: Sequence[str]) -> list[list[str]]:
    """`ids` in requests of at most IDS_MAX (what the Task Manager answers of one request);
    no ids: one request without any, which asks for every one."""
    return [list(ids[i : i + IDS_MAX]) for i in range(0, len(ids), IDS_MAX)] or [[]]


class ClientParts:
    """What every part of TaskManagerClient stands on (the mixins of watching.py, history.py,
    interventions.py and scheduling.py): a call of one of the Task Manager's services, and a
    system task run to its end. TaskManagerClient gives both; a test may give its own."""

    def _call(
        self, service_type: Any, name: str, request: Any, timeout_sec: float | None = None
    ) -> Any:
        """Call a Task Manager service that may be asked again (ServiceCalls.call)."""
        raise NotImplementedError

    def _system_task(
        self, task_name: str, data: dict[str, Any], *, source: str, timeout_sec: float | None
    ) -> TaskResult:
        """Run a system task with this task data as `source`; its result, waited for at most
        `timeout_sec` (None: no limit)."""
        raise NotImplementedError


class ServiceCalls:
    """This client's clients of the Task Manager's services, each made on first use."""

    def __init__(self, connection: Connection) -> None:
        self._connection = connection
        # key: service name, value: this client's client of it
        self._clients: dict[str, Client[Any, Any]] = {}

    def call(
        self, service_type: Any, name: str, request: Any, timeout_sec: float | None = None
    ) -> Any:
        """Call a Task Manager service that only reads, or takes a repeat as the first (see
        confirm_task); a lost reply is asked for again."""
        check_wait_seconds(timeout_sec)
        timeout_sec = self._connection.timeout_sec if timeout_sec is None else timeout_sec
        deadline = time.monotonic() + timeout_sec
        client = self._client(service_type, name)
        if not wait_until_ready(client.service_is_ready, timeout_sec):
            raise TaskManagerUnavailable(f'{name} is not available')
        answered = threading.Event()
        calls: list[Future[Any]] = []
        retry_sec = SERVICE_RETRY_SEC
        while not answered.is_set() and (remaining_sec := deadline - time.monotonic()) > 0:
            calls.append(client.call_async(request))
            calls[-1].add_done_callback(lambda _: answered.set())
            answered.wait(min(retry_sec, remaining_sec))
            retry_sec *= 2
        response = next((c.result() for c in calls if c.done() and c.result() is not None), None)
        for call in calls:
            client.remove_pending_request(call)
        if response is None:
            raise TaskManagerUnavailable(f'{name} did not answer within {timeout_sec} s')
        return response

    def wait_until_ready(self, names: Collection[str], timeout_sec: float) -> None:
        """Wait until each service of `names` (keys of SERVICE_TYPES) has met this client
        (its client is made now); TaskManagerUnavailable naming the first that has not within
        `timeout_sec` in all."""
        deadline = time.monotonic() + timeout_sec
        for name in names:
            client = self._client(SERVICE_TYPES[name], name)
            if not wait_until_ready(client.service_is_ready, max(0.0, deadline - time.monotonic())):
                raise TaskManagerUnavailable(f'{name} is not available')

    def all_met(self) -> bool:
        """Whether every service this client has used so far has met it (a newcomer's
        participant can meet some of the node and never one of its services)."""
        with self._connection.lock:
            clients = list(self._clients.values())
        return all(client.service_is_ready() for client in clients)

    def _client(self, service_type: Any, name: str) -> Client[Any, Any]:
        """This client's client of the service `name`, made on first use."""
        with self._connection.lock:
            client = self._clients.get(name)
            if client is None:
                client = self._clients[name] = self._connection.node.create_client(
                    service_type, name
                )
            return client
