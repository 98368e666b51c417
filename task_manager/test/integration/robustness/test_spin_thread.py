"""SpinThread: stopping a background executor thread cannot lose its wake-up, unlike rclpy's
Executor.shutdown() from another thread, and the thread has ended when `stop` returns."""

import os
import threading
from collections.abc import Iterator
from typing import Any

import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from task_manager import TaskManagerClient
from task_manager.rclpy_tools.spin_thread import SpinThread

pytestmark = pytest.mark.ros
TIMEOUT_SEC = 5.0
# How long a thread that should be waiting is given to show it is not: a thread that was woken
# ends within milliseconds.
STILL_WAITING_SEC = 0.5


@pytest.fixture
def node(ros_context: None) -> Iterator[Node]:
    node = rclpy.create_node(f'spin_thread_{os.getpid()}')
    yield node
    node.destroy_node()


class ShutdownWhileGathering(SingleThreadedExecutor):
    """Calls its own `shutdown()` once, as another thread's could land: after `spin` checked it
    is not shut down and before it reads the guard condition that shutdown triggers."""

    def __init__(self) -> None:
        super().__init__()
        self.armed = False

    def can_execute(self, entity: Any) -> bool:
        if self.armed:
            self.armed = False
            self.shutdown()
        return super().can_execute(entity)


def test_rclpys_shutdown_between_the_check_and_the_wait_leaves_spin_waiting(node: Node) -> None:
    """Why SpinThread exists: if rclpy ever fixes this, the workaround can go."""
    executor = ShutdownWhileGathering()
    executor.add_node(node)
    wake = node.create_guard_condition(lambda: None)
    executor.armed = True
    spinning = threading.Thread(target=executor.spin, daemon=True)
    spinning.start()

    spinning.join(STILL_WAITING_SEC)
    still_waiting = spinning.is_alive()
    wake.trigger()  # what else wakes it: the loop then sees the shutdown
    spinning.join(TIMEOUT_SEC)

    assert still_waiting, 'rclpy woke the thread: its lost wake-up is fixed'
    assert not spinning.is_alive()


def test_stop_wakes_a_thread_waiting_with_nothing_ready_and_joins_it(node: Node) -> None:
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    spinner = SpinThread(executor, node, 'spin-thread-test', lambda error: None)
    spinner.start()
    ran = threading.Event()
    executor.create_task(ran.set)
    assert ran.wait(TIMEOUT_SEC)  # the thread spins, then waits: nothing else is ready

    ended = spinner.stop(TIMEOUT_SEC)  # without a wake-up, it would wait on to the timeout

    assert ended
    executor.shutdown()


def test_stop_returns_after_the_callback_in_progress_ends(node: Node) -> None:
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    spinner = SpinThread(executor, node, 'spin-thread-test', lambda error: None)
    spinner.start()
    inside, release = threading.Event(), threading.Event()

    def held() -> None:
        inside.set()
        release.wait(TIMEOUT_SEC)

    executor.create_task(held)
    assert inside.wait(TIMEOUT_SEC)
    results: list[bool] = []
    stopping = threading.Thread(target=lambda: results.append(spinner.stop(TIMEOUT_SEC)))
    stopping.start()

    stopping.join(STILL_WAITING_SEC)
    returned_during_the_callback = not stopping.is_alive()
    release.set()
    stopping.join(TIMEOUT_SEC)

    assert not returned_during_the_callback
    assert results == [True]
    executor.shutdown()


def test_an_error_of_the_executor_goes_to_on_error_and_the_thread_spins_on(node: Node) -> None:
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    errors: list[Exception] = []
    spinner = SpinThread(executor, node, 'spin-thread-test', errors.append)
    spinner.start()

    def fail() -> None:
        raise ValueError('in a callback')

    executor.create_task(fail)
    ran = threading.Event()
    executor.create_task(ran.set)

    assert ran.wait(TIMEOUT_SEC)
    assert [str(error) for error in errors] == ['in a callback']
    assert spinner.stop(TIMEOUT_SEC)
    executor.shutdown()


def test_a_client_closed_twice_closes_once(ros_context: None) -> None:
    client = TaskManagerClient('closed_twice', timeout_sec=TIMEOUT_SEC)
    client.close()

    client.close()  # the node and its guard condition are gone: nothing to wake


def test_without_on_error_an_error_of_the_executor_ends_the_thread(node: Node) -> None:
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    spinner = SpinThread(executor, node, 'spin-thread-ended-by-an-error')
    spinner.start()
    (thread,) = [t for t in threading.enumerate() if t.name == 'spin-thread-ended-by-an-error']

    def fail() -> None:
        raise ValueError('in a callback')

    executor.create_task(fail)
    thread.join(TIMEOUT_SEC)  # not stopped: only the error ends it

    assert not thread.is_alive()
    assert spinner.stop(TIMEOUT_SEC)
    executor.shutdown()
