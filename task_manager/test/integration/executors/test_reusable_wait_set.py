"""The executors' wait set, kept between turns: made once while the nodes' entities stay the
same, made again when one comes or goes, never holding an entity that may not run, never
keeping a destroyed one alive; and publishers that add nothing to it."""

import os
import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest
import rclpy
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.exceptions import InvalidHandle
from rclpy.task import Future
from test_msgs.msg import Empty

from task_manager.rclpy_tools import qos
from task_manager.rclpy_tools.qos import DEEP_RELIABLE
from task_manager.rclpy_tools.reusable_wait_set import ReusableWaitSet
from task_manager.rclpy_tools.server_wait import wait_until_ready
from task_manager.rclpy_tools.wakeless_executor import WakelessExecutor
from task_manager.ros import parking_executor
from task_manager.ros.parking_executor import ParkingExecutor

pytestmark = pytest.mark.ros
MESSAGES = 5
TIMEOUT_SEC = 5.0
IDLE_SPINS = 5
IDLE_WAIT_SEC = 0.02


class Counts:
    """How many wait sets were made, and how many waits they did."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.made = 0
        self.waits = 0
        make, wait = ReusableWaitSet.__init__, ReusableWaitSet.wait

        def counted_make(wait_set: ReusableWaitSet, *args: Any) -> None:
            self.made += 1
            make(wait_set, *args)

        def counted_wait(wait_set: ReusableWaitSet, timeout_nsec: int) -> Any:
            self.waits += 1
            return wait(wait_set, timeout_nsec)

        monkeypatch.setattr(ReusableWaitSet, '__init__', counted_make)
        monkeypatch.setattr(ReusableWaitSet, 'wait', counted_wait)


class Topic:
    """A subscription of the node and a publisher to it; what it received."""

    def __init__(self, node: rclpy.node.Node, name: str, **options: Any) -> None:
        self.received: list[Empty] = []
        topic = f'/{name}_{os.getpid()}'
        self.subscription = node.create_subscription(
            Empty, topic, self.received.append, DEEP_RELIABLE, **options
        )
        self.publisher = node.create_publisher(Empty, topic, DEEP_RELIABLE)
        assert wait_until_ready(lambda: self.publisher.get_subscription_count() == 1, 5.0)

    def send_and_spin(self, executor: WakelessExecutor) -> None:
        """Publish one message and spin until the subscription has it."""
        count = len(self.received) + 1
        self.publisher.publish(Empty())
        deadline = time.monotonic() + TIMEOUT_SEC
        while len(self.received) < count and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=TIMEOUT_SEC)
        assert len(self.received) == count


@pytest.fixture
def node(ros_context: None) -> Iterator[rclpy.node.Node]:
    node = rclpy.create_node(f'wait_set_{os.getpid()}')
    yield node
    node.destroy_node()


@pytest.fixture
def executor(node: rclpy.node.Node) -> Iterator[WakelessExecutor]:
    """A WakelessExecutor of the node, spun by the test."""
    executor = WakelessExecutor()
    executor.add_node(node)
    yield executor
    executor.shutdown()


def test_the_wait_set_is_made_once_while_the_entities_stay(
    node: rclpy.node.Node, executor: WakelessExecutor, monkeypatch: pytest.MonkeyPatch
) -> None:
    topic = Topic(node, 'kept')
    counts = Counts(monkeypatch)
    for _ in range(MESSAGES):
        topic.send_and_spin(executor)
        executor.spin_once(timeout_sec=IDLE_WAIT_SEC)
    assert (counts.made, counts.waits) == (1, 2 * MESSAGES)  # rclpy's makes one per wait


def test_an_entity_made_or_destroyed_makes_it_again(
    node: rclpy.node.Node, executor: WakelessExecutor, monkeypatch: pytest.MonkeyPatch
) -> None:
    first = Topic(node, 'first')
    first.send_and_spin(executor)
    counts = Counts(monkeypatch)
    second = Topic(node, 'second')
    second.send_and_spin(executor)  # waited on from the turn after it was made
    first.send_and_spin(executor)
    assert counts.made == 1
    node.destroy_subscription(second.subscription)
    first.send_and_spin(executor)
    assert counts.made == 2
    with pytest.raises(InvalidHandle), second.subscription.handle:
        pass  # destroyed: the wait set released it


def test_an_entity_destroyed_from_another_thread_is_released_while_the_executor_waits(
    node: rclpy.node.Node,
) -> None:
    """The wait set holds its entities' handles only while it waits, as rclpy's does: one
    destroyed meanwhile is gone once that wait returns (its destroy wakes the executor)."""
    kept, gone = Topic(node, 'stays'), Topic(node, 'goes')
    executor = WakelessExecutor()
    executor.add_node(node)
    spinning = threading.Thread(target=executor.spin)
    spinning.start()
    try:
        assert wait_until_ready(lambda: executor._kept is not None, TIMEOUT_SEC)
        node.destroy_subscription(gone.subscription)

        def released() -> bool:
            try:
                with gone.subscription.handle:
                    return False
            except InvalidHandle:
                return True

        assert wait_until_ready(released, TIMEOUT_SEC)
        kept.publisher.publish(Empty())
        assert wait_until_ready(lambda: len(kept.received) == 1, TIMEOUT_SEC)
    finally:
        executor.shutdown()
        spinning.join(TIMEOUT_SEC)
    assert not spinning.is_alive()


def test_an_entity_whose_callback_group_is_busy_is_not_waited_on(
    node: rclpy.node.Node, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A message for a subscription whose mutually exclusive group is running a callback
    waits in its reader: waiting on it would return at once, turn after turn."""
    parking_executor.install()
    group = MutuallyExclusiveCallbackGroup()
    answer: Future[None] = Future()

    async def awaiting() -> None:
        await answer

    guard = node.create_guard_condition(awaiting, callback_group=group)  # type: ignore[arg-type]
    guard.trigger()  # rclpy runs a coroutine callback as a task, typed or not
    topic = Topic(node, 'busy', callback_group=group)
    executor = ParkingExecutor()
    executor.add_node(node)
    executor.spin_once(timeout_sec=0.0)  # the guard's callback, up to its await
    topic.publisher.publish(Empty())
    counts = Counts(monkeypatch)
    for _ in range(IDLE_SPINS):
        executor.spin_once(timeout_sec=IDLE_WAIT_SEC)
    assert topic.received == [] and counts.waits == IDLE_SPINS  # each wait timed out
    answer.set_result(None)
    deadline = time.monotonic() + TIMEOUT_SEC
    while not topic.received and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=TIMEOUT_SEC)
    assert len(topic.received) == 1
    executor.shutdown()


def test_publishers_without_qos_events_add_nothing_to_wait_on(node: rclpy.node.Node) -> None:
    """rclpy gives each publisher two incompatible-QoS handlers, two waitables in every wait:
    the node's publishers have none, and its /parameter_events publisher's are taken out."""
    assert len(list(node.waitables)) == 2  # rclpy's, of /parameter_events
    qos.drop_qos_events(node, node._parameter_event_publisher)
    publisher = node.create_publisher(
        Empty, f'/quiet_{os.getpid()}', DEEP_RELIABLE, event_callbacks=qos.without_qos_events()
    )
    assert list(node.waitables) == [] and publisher.event_handlers == []
