"""The servers the benchmarked tasks run on, in a process of their own (`python -m bench.servers`).

Minimal and fast: instant goals and calls end in their first callback, and the instant action
server keeps no finished goals (see lean_action.py). The hold server is a regular rclpy
ActionServer whose goals are kept accepted but not executing, so a thousand of them cost no
pending coroutine in this process's executor; `/bench/release_goals` executes them all. Held
calls of the slow service wait on futures until `/bench/release_calls`.
"""

from typing import Any

import rclpy
from rclpy.action import ActionServer
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.task import Future
from std_srvs.srv import Trigger
from test_msgs.action import Fibonacci

from bench import config
from bench.lean_action import InstantActionServer
from task_manager.ros.cleanup import destroy_waitables
from task_manager.ros.qos import DEEP_RELIABLE

SERVER_NODE_NAME = 'task_manager_bench_servers'


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
        self._held_calls: list[Future] = []
        self._wake = node.create_guard_condition(lambda: None, group)
        self._instant = InstantActionServer(
            node, Fibonacci, config.FIBONACCI_TOPIC, fibonacci_result, group
        )
        self._hold = ActionServer(
            node,
            Fibonacci,
            config.HOLD_TOPIC,
            execute_callback=finish_fibonacci,
            handle_accepted_callback=self._held_goals.append,
            goal_service_qos_profile=DEEP_RELIABLE,
            result_service_qos_profile=DEEP_RELIABLE,
            cancel_service_qos_profile=DEEP_RELIABLE,
            callback_group=group,
        )
        for topic, callback in (
            (config.TRIGGER_TOPIC, answer_trigger),
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
        released: Future = Future()
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


def main() -> None:
    rclpy.init()
    node = rclpy.create_node(SERVER_NODE_NAME)
    executor = SingleThreadedExecutor()
    BenchServers(node)
    executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        executor.shutdown()
        destroy_waitables(node)
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
