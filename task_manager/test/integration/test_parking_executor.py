"""ParkingExecutor: a coroutine waiting on a future is not stepped until the future completes."""

import os
import threading
import time

import pytest
import rclpy
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.client import Client
from rclpy.task import Future
from std_srvs.srv import Trigger

from task_manager.rclpy_tools.futures import resolved
from task_manager.ros import parking_executor
from task_manager.ros.parking_executor import ParkingExecutor

pytestmark = pytest.mark.ros
UNRELATED_WAKE_UPS = 20


class CountingFuture(Future[int]):
    """Counts how often an awaiting coroutine checked it (once per step of the coroutine)."""

    def __init__(self) -> None:
        super().__init__()
        self.checks = 0

    def _pending(self) -> bool:
        self.checks += 1
        return super()._pending()


def test_a_waiting_coroutine_is_stepped_only_when_its_future_completes(ros_context: None) -> None:
    parking_executor.install()
    executor = ParkingExecutor()
    future = CountingFuture()
    seen: list[int | None] = []

    async def waiter() -> None:
        seen.append(await future)

    task = executor.create_task(waiter)
    executor.spin_once(timeout_sec=0.0)  # runs it up to the await
    checks_at_the_await = future.checks
    for _ in range(UNRELATED_WAKE_UPS):
        executor.create_task(lambda: None)
        executor.spin_once(timeout_sec=0.0)
    assert future.checks == checks_at_the_await  # rclpy's executor steps it at each wake-up

    threading.Thread(target=future.set_result, args=(7,)).start()  # from another thread
    executor.spin_until_future_complete(task, timeout_sec=5.0)
    assert task.done() and seen == [7]
    executor.shutdown()


def test_a_coroutine_awaiting_a_future_already_done_goes_on_at_once(ros_context: None) -> None:
    parking_executor.install()
    executor = ParkingExecutor()
    done: Future[int] = Future()
    done.set_result(3)

    async def twice() -> int:
        return (await done or 0) + (await done or 0)

    task = executor.create_task(twice)
    executor.spin_until_future_complete(task, timeout_sec=5.0)
    assert task.result() == 6
    executor.shutdown()


def test_an_async_service_callback_waiting_on_a_future_is_parked_too(ros_context: None) -> None:
    parking_executor.install()
    executor = ParkingExecutor()
    node = rclpy.create_node(f'parking_{os.getpid()}')
    executor.add_node(node)
    future = CountingFuture()
    entered = threading.Event()

    async def answer(_: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        entered.set()
        response.success = bool(await future)
        return response

    name = f'/parking_{os.getpid()}/answer'
    node.create_service(Trigger, name, answer, callback_group=ReentrantCallbackGroup())
    client: Client[Trigger.Request, Trigger.Response] = node.create_client(Trigger, name)
    assert client.wait_for_service(timeout_sec=5.0)
    reply = client.call_async(Trigger.Request())
    deadline = time.monotonic() + 5.0
    while not entered.is_set() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.1)
    assert entered.is_set()
    checks_at_the_await = future.checks
    for _ in range(UNRELATED_WAKE_UPS):
        executor.create_task(lambda: None)
        executor.spin_once(timeout_sec=0.0)
    assert future.checks == checks_at_the_await  # rclpy's handler task steps it at each wake-up

    future.set_result(1)
    executor.spin_until_future_complete(reply, timeout_sec=5.0)
    response = reply.result()
    assert reply.done() and response is not None and response.success
    executor.shutdown()
    node.destroy_node()


def test_a_coroutine_in_resolved_goes_on_when_its_future_completes_with_no_wake_up_task(
    ros_context: None,
) -> None:
    parking_executor.install()
    executor = ParkingExecutor()
    assert executor.resumes_waiters  # resolved() queues no wake-up task on it
    node = rclpy.create_node(f'parking_resolved_{os.getpid()}')
    executor.add_node(node)
    future: Future[int] = Future()
    task = executor.create_task(resolved, node, future)
    executor.spin_once(timeout_sec=0.0)  # up to its await, where it parks
    threading.Thread(target=future.set_result, args=(5,)).start()
    started = time.monotonic()
    executor.spin_until_future_complete(task, timeout_sec=5.0)
    assert task.result() == 5 and time.monotonic() - started < 1.0
    executor.shutdown()
    node.destroy_node()
