"""An in-process ROS node spun in a background thread, with bounded waits for tests."""

import threading
import weakref
from collections.abc import Callable
from typing import Any, TypeVar, cast

import rclpy
from rclpy.action.client import ActionClient
from rclpy.event_handler import QoSSubscriptionMatchedInfo, SubscriptionEventCallbacks
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.task import Future

from task_manager.rclpy_tools.cleanup import destroy_waitables
from task_manager.rclpy_tools.spin_thread import SpinThread

T = TypeVar('T')


class WaitTimeoutError(AssertionError):
    """A bounded wait in a test ran out before the awaited event happened."""


def wait_for_future(future: Future[Any], timeout_sec: float, what: str = 'future') -> Any:
    """Block the calling (non-executor) thread until `future` completes; return its result."""
    done = threading.Event()
    future.add_done_callback(lambda _: done.set())
    if not done.wait(timeout_sec) and not future.done():
        raise WaitTimeoutError(f'{what} not done within {timeout_sec} s')
    return future.result()


class TopicRecorder:
    """Records every message of a topic; tests wait on conditions over the record."""

    def __init__(self, node: Node, msg_type: type, topic: str, qos: QoSProfile | int) -> None:
        self.messages: list[Any] = []
        self.matched_publishers = 0
        self._node = node
        self._changed = threading.Condition()
        self.subscription = node.create_subscription(
            msg_type,
            topic,
            self._on_message,
            qos,
            event_callbacks=SubscriptionEventCallbacks(matched=self._on_matched),
        )

    def _on_matched(self, info: QoSSubscriptionMatchedInfo) -> None:
        with self._changed:
            self.matched_publishers = info.current_count
            self._changed.notify_all()

    def wait_matched(self, timeout_sec: float) -> None:
        """Wait until a publisher is connected, so nothing it publishes from now is missed."""
        with self._changed:
            if not self._changed.wait_for(lambda: self.matched_publishers > 0, timeout_sec):
                raise WaitTimeoutError(f'no publisher matched within {timeout_sec} s')

    def _on_message(self, msg: Any) -> None:
        with self._changed:
            self.messages.append(msg)
            self._changed.notify_all()

    def wait_until(
        self,
        predicate: Callable[[list[Any]], T | None],
        timeout_sec: float,
        what: str = 'condition',
    ) -> T:
        """Wait until `predicate(messages)` is truthy and return its value."""
        with self._changed:
            value = self._changed.wait_for(lambda: predicate(self.messages), timeout_sec)
            if not value:
                raise WaitTimeoutError(f'{what} not met within {timeout_sec} s')
            return value

    def snapshot(self) -> list[Any]:
        with self._changed:
            return list(self.messages)

    def destroy(self) -> None:
        """Destroy its subscription (on the thread spinning the node: see RosHarness.destroy)."""
        self._node.destroy_subscription(self.subscription)


# The harness spinning each node, for destroy_on_executor.
_HARNESSES: 'weakref.WeakValueDictionary[int, RosHarness]' = weakref.WeakValueDictionary()


def destroy_on_executor(node: Node, entity: Any) -> None:
    """Destroy `entity` (an action client or server of `node`) on the thread spinning `node`.

    rclpy frees an action entity's handle before it leaves the node's waitables: destroyed on
    another thread, a turn of the executor in between adds the freed handle to its wait set and
    raises ('action client pointer is invalid'). Where no harness spins `node`, destroys at once.
    """
    harness = _HARNESSES.get(id(node))
    if harness is None or harness.node is not node:
        entity.destroy()
    else:
        harness.destroy(entity)


class CallbackError(AssertionError):
    """A callback on the harness's executor (a test double's) raised; raised at close."""


class RosHarness:
    """Owns one node and a single-threaded executor spinning it in a background thread.

    Single-threaded on purpose: a shared multi-threaded executor delays deliveries
    under load (see ROS2_FROM_PYPI.md), which would make tests slow and flaky.

    A callback that raises does not stop the spinning (the test's other waits would only time
    out, far from the cause): its exception is kept, and `close` raises it.
    """

    def __init__(self, node_name: str) -> None:
        self.node = rclpy.create_node(node_name)
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self.callback_errors: list[Exception] = []
        self._closing = False
        _HARNESSES[id(self.node)] = self
        self._spinner = SpinThread(
            self.executor, self.node, f'{node_name}-spin', self.callback_errors.append
        )
        self._spinner.start()

    def on_executor(self, function: Callable[[], T], timeout_sec: float = 10.0) -> T:
        """Run `function` on the executor thread and return its result.

        rclpy's ActionClient joins the node's waitables before it has its lock: made on
        another thread while the executor spins, the executor may see it half-built and die.
        Build action clients through this.
        """
        task = self.executor.create_task(function)
        return cast(T, wait_for_future(task, timeout_sec, 'executor task'))

    def action_client(self, action_type: type, name: str, **options: Any) -> Any:
        """An rclpy ActionClient on this node, built on the executor thread (see on_executor)."""
        return self.on_executor(lambda: ActionClient(self.node, action_type, name, **options))

    def send_goal(
        self, client: Any, goal: Any, feedback_callback: Callable[[Any], None] | None = None
    ) -> Future[Any]:
        """`client.send_goal_async(goal)` on the executor thread; the goal response's future.

        rclpy 9.1's ActionClient.send_goal_async registers its future a second time outside its
        lock: sent from another thread, a response handled in between raises ValueError
        ('list.remove(x): x not in list'). Send goals of the harness's clients through this.
        """
        if self._spinner.is_current():
            return cast(
                Future[Any], client.send_goal_async(goal, feedback_callback=feedback_callback)
            )
        return self.on_executor(
            lambda: client.send_goal_async(goal, feedback_callback=feedback_callback)
        )

    def destroy(self, *entities: Any) -> None:
        """Destroy action clients and servers, recorders (what has `destroy()`) of this node on
        the thread spinning it (see destroy_on_executor)."""
        for entity in entities:
            if self._closing or self._spinner.is_current():
                entity.destroy()
            else:
                self.on_executor(entity.destroy)

    def record(self, msg_type: type, topic: str, qos: QoSProfile | int = 10) -> TopicRecorder:
        return TopicRecorder(self.node, msg_type, topic, qos)

    def close(self) -> None:
        """Stop spinning and destroy the node; raises CallbackError if a callback raised."""
        self._closing = True
        assert self._spinner.stop(timeout_sec=5.0), 'a callback on the test node did not return'
        self.executor.shutdown()
        destroy_waitables(self.node)
        self.node.destroy_node()
        if self.callback_errors:
            first = self.callback_errors[0]
            raise CallbackError(
                f'{len(self.callback_errors)} callback(s) on the test node raised, the first: '
                f'{first!r}'
            ) from first
