"""The servers the benchmarked tasks run on, in a process of their own (`python -m bench.servers`).

Each server the node's tasks use has a twin under a name of its own for the bench's direct
baselines (see config.DIRECT_FIBONACCI_TOPIC). Minimal and fast: instant goals and calls end in
their first callback, and the instant action server keeps no finished goals (see
lean_action.py). The hold server is a regular rclpy ActionServer whose goals are kept accepted
but not executing, so a thousand of them cost no pending coroutine in this process's executor;
`/bench/release_goals` executes them all. Held calls of the slow service wait on futures until
`/bench/release_calls`. The feedback server's goals publish feedback at 100 Hz, from one rclpy
timer, until `/bench/release_feedback`.
"""

import json
import time
from typing import Any

from rclpy.action.server import ActionServer
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.task import Future
from rclpy.timer import Timer
from std_srvs.srv import Trigger
from test_msgs.action import Fibonacci

from bench.harness import config
from bench.harness.lean_action import InstantActionServer
from bench.harness.processes import spin_child
from task_manager.rclpy_tools.qos import DEEP_RELIABLE

SERVER_NODE_NAME = 'task_manager_bench_servers'
FEEDBACK_SEQUENCE_LENGTH = 10


def fibonacci_sequence(order: int) -> list[int]:
    sequence = [0, 1][: order + 1]
    while len(sequence) <= order:
        sequence.append(sequence[-1] + sequence[-2])
    return sequence


def fibonacci_result(goal: Fibonacci.Goal) -> Fibonacci.Result:
    return Fibonacci.Result(sequence=fibonacci_sequence(goal.order))


def finish_fibonacci(goal_handle: Any) -> Fibonacci.Result:
    goal_handle.succeed()
    return fibonacci_result(goal_handle.request)


def answer_trigger(_request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
    response.success = True
    return response


class BenchServers:
    """Every server of the bench, on one node."""

    def __init__(self, node: Node) -> None:
        group = ReentrantCallbackGroup()
        # goals accepted by the hold server and not yet executed
        self._held_goals: list[Any] = []
        # futures of slow-service calls still waiting for their response
        self._held_calls: list[Future[Any]] = []
        self._wake = node.create_guard_condition(lambda: None, group)
        self._feedback = FeedbackServer(node, group, self._wake.trigger)
        # each server twice: for the node's tasks, and under a name of its own for the bench's
        # direct baselines (config.DIRECT_FIBONACCI_TOPIC); the instant one a third time, for
        # the throughput benchmark's floor relay (relay.py)
        self._instant = [
            InstantActionServer(node, Fibonacci, topic, fibonacci_result, group)
            for topic in (
                config.FIBONACCI_TOPIC,
                config.DIRECT_FIBONACCI_TOPIC,
                config.RELAY_FIBONACCI_TOPIC,
            )
        ]
        self._hold = [
            ActionServer(
                node,
                Fibonacci,
                topic,
                execute_callback=finish_fibonacci,
                handle_accepted_callback=self._held_goals.append,
                goal_service_qos_profile=DEEP_RELIABLE,
                result_service_qos_profile=DEEP_RELIABLE,
                cancel_service_qos_profile=DEEP_RELIABLE,
                callback_group=group,
            )
            for topic in (config.HOLD_TOPIC, config.DIRECT_HOLD_TOPIC)
        ]
        for topic, callback in (
            (config.TRIGGER_TOPIC, answer_trigger),
            (config.DIRECT_TRIGGER_TOPIC, answer_trigger),
            (config.SLOW_SERVICE_TOPIC, self._hold_call),
            (config.RELEASE_GOALS_TOPIC, self._release_goals),
            (config.RELEASE_CALLS_TOPIC, self._release_calls),
        ):
            node.create_service(
                Trigger, topic, callback, qos_profile=DEEP_RELIABLE, callback_group=group
            )

    async def _hold_call(
        self, _request: Trigger.Request, response: Trigger.Response
    ) -> Trigger.Response:
        released: Future[Any] = Future()
        self._held_calls.append(released)
        await released
        response.success = True
        return response

    def _release_goals(
        self, _request: Trigger.Request, response: Trigger.Response
    ) -> Trigger.Response:
        held = list(self._held_goals)
        self._held_goals.clear()
        for goal_handle in held:
            goal_handle.execute()
        response.success = True
        response.message = f'released {len(held)} goal(s)'
        return response

    def _release_calls(
        self, _request: Trigger.Request, response: Trigger.Response
    ) -> Trigger.Response:
        held = list(self._held_calls)
        self._held_calls.clear()
        for released in held:
            released.set_result(None)
        self._wake.trigger()  # resume the held calls' coroutines at once
        response.success = True
        response.message = f'released {len(held)} call(s)'
        return response


class FeedbackServer:
    """Goals that publish feedback at FEEDBACK_RATE_HZ until released, then succeed.

    One rclpy timer publishes the feedback of every running goal; it exists only while a
    goal runs, so it wakes this process's executor during the feedback benchmark alone.
    """

    def __init__(self, node: Node, group: ReentrantCallbackGroup, wake: Any) -> None:
        self._node = node
        self._group = group
        self._wake = wake
        # the running goals, each with the future that releases it
        self._running: list[tuple[Any, Future[Any]]] = []
        self._timer: Timer | None = None
        self._published = 0
        self._started_at = 0.0
        self._server = ActionServer(
            node,
            Fibonacci,
            config.FEEDBACK_TOPIC,
            execute_callback=self._execute,
            goal_service_qos_profile=DEEP_RELIABLE,
            result_service_qos_profile=DEEP_RELIABLE,
            cancel_service_qos_profile=DEEP_RELIABLE,
            callback_group=group,
        )
        node.create_service(
            Trigger,
            config.RELEASE_FEEDBACK_TOPIC,
            self._release,
            qos_profile=DEEP_RELIABLE,
            callback_group=group,
        )

    async def _execute(self, goal_handle: Any) -> Fibonacci.Result:
        released: Future[Any] = Future()
        self._running.append((goal_handle, released))
        if self._timer is None:
            self._published = 0
            self._started_at = time.monotonic()
            self._timer = self._node.create_timer(
                1.0 / config.FEEDBACK_RATE_HZ, self._publish, self._group
            )
        await released
        goal_handle.succeed()
        return fibonacci_result(goal_handle.request)

    def _publish(self) -> None:
        # a sequence that changes with every message, as a robot's progress does
        start = self._published
        feedback = Fibonacci.Feedback(sequence=list(range(start, start + FEEDBACK_SEQUENCE_LENGTH)))
        for goal_handle, _ in self._running:
            goal_handle.publish_feedback(feedback)
            self._published += 1

    def _release(self, _request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        """End every running goal; the message says how much feedback they published (JSON)."""
        running = list(self._running)
        self._running.clear()
        if self._timer is not None:
            self._node.destroy_timer(self._timer)
            self._timer = None
        for _, released in running:
            released.set_result(None)
        self._wake()  # resume the goals' coroutines at once
        response.success = True
        response.message = json.dumps(
            {
                'goals': len(running),
                'feedback_messages': self._published,
                'seconds': time.monotonic() - self._started_at,
            }
        )
        return response


def main() -> None:
    spin_child(SERVER_NODE_NAME, BenchServers)


if __name__ == '__main__':
    main()
