"""Service requests through rclpy_tools.calls: every answered, cancelled or forgotten request
leaves its client's table of pending requests, on the node's executor and on rclpy's; on the
node's, an answer costs no task beyond its handler."""

import os
from collections.abc import Iterator
from typing import Any

import pytest
import rclpy
from rclpy.client import Client
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.task import Future
from std_srvs.srv import Empty, Trigger

from task_manager.rclpy_tools.calls import call_async, forget
from task_manager.rclpy_tools.futures import all_completed
from task_manager.rclpy_tools.qos import DEEP_RELIABLE
from task_manager.rclpy_tools.server_wait import wait_until_ready
from task_manager.ros import parking_executor
from task_manager.ros.parking_executor import ParkingExecutor

pytestmark = pytest.mark.ros
BURST = 200
TIMEOUT_SEC = 10.0


@pytest.fixture
def served(ros_context: None) -> Iterator[tuple[Node, Client[Any, Any]]]:
    """A node serving Trigger, and a client of that service on the same node."""
    parking_executor.install()
    node = rclpy.create_node(f'calls_{os.getpid()}')
    service = f'/calls_{os.getpid()}'
    node.create_service(Trigger, service, lambda _, answer: answer, qos_profile=DEEP_RELIABLE)
    client: Client[Any, Any] = node.create_client(Trigger, service, qos_profile=DEEP_RELIABLE)
    assert wait_until_ready(client.service_is_ready, TIMEOUT_SEC)
    yield node, client
    node.destroy_node()


def _answer_a_burst(
    executor: SingleThreadedExecutor, node: Node, client: Client[Any, Any]
) -> list[Future[Any]]:
    executor.add_node(node)
    replies = [call_async(client, Trigger.Request()) for _ in range(BURST)]
    everything = all_completed(replies)
    executor.spin_until_future_complete(everything, timeout_sec=TIMEOUT_SEC)
    executor.shutdown()
    assert everything.done()
    return replies


def test_a_burst_answered_on_the_parking_executor_leaves_nothing_pending_and_no_extra_tasks(
    served: tuple[Node, Client[Any, Any]], monkeypatch: pytest.MonkeyPatch
) -> None:
    node, client = served
    tasks = [0]
    made = parking_executor._ParkingTask.__init__

    def counted(task: Any, *args: Any) -> None:
        tasks[0] += 1
        made(task, *args)

    monkeypatch.setattr(parking_executor._ParkingTask, '__init__', counted)
    replies = _answer_a_burst(ParkingExecutor(), node, client)

    assert all(isinstance(reply.result(), Trigger.Response) for reply in replies)
    assert client._pending_requests == {}
    # a handler for each request and one for each response; rclpy's call_async made a task
    # for each answer besides, and a take that found nothing left cost a task too
    assert tasks[0] <= 2 * BURST + 2, tasks[0]


def test_a_burst_answered_on_rclpys_executor_leaves_nothing_pending(
    served: tuple[Node, Client[Any, Any]],
) -> None:
    node, client = served
    replies = _answer_a_burst(SingleThreadedExecutor(), node, client)
    assert all(isinstance(reply.result(), Trigger.Response) for reply in replies)
    assert client._pending_requests == {}


def test_a_cancelled_or_forgotten_request_leaves_the_table_and_the_others_stay(
    ros_context: None,
) -> None:
    node = rclpy.create_node(f'calls_unserved_{os.getpid()}')
    try:
        client: Client[Any, Any] = node.create_client(Trigger, f'/nobody_{os.getpid()}')
        first, second, third = (call_async(client, Trigger.Request()) for _ in range(3))
        first.cancel()
        forget(client, third)  # its caller waits no more: out of the table, the future as it is
        assert list(client._pending_requests.values()) == [second]
        assert not third.done()
        with pytest.raises(TypeError, match='Empty_Request is not a request of Trigger'):
            call_async(client, Empty.Request())
    finally:
        node.destroy_node()
