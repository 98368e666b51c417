"""A process serving an action and a service that never finish, for server-loss tests.

Run: python -m task_manager.testing.stuck_servers ACTION_TOPIC SERVICE_TOPIC
It prints `stuck servers ready` once both are up; kill it to make the servers vanish.
"""

import contextlib
import sys
from pathlib import Path
from typing import Any

import rclpy
from rclpy.action.server import ActionServer, CancelResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.task import Future
from std_srvs.srv import SetBool
from test_msgs.action import Fibonacci

READY_LINE = 'stuck servers ready'
SHORT_LEASE_PROFILE = Path(__file__).with_name('short_lease_fastdds.xml')


async def _never_ending_goal(goal_handle: Any) -> Fibonacci.Result:
    await Future()
    return Fibonacci.Result()


async def _never_answered_call(request: Any, response: Any) -> Any:
    await Future()
    return response


def main() -> None:
    action_topic, service_topic = sys.argv[1], sys.argv[2]
    rclpy.init()
    node = rclpy.create_node('stuck_servers')
    group = ReentrantCallbackGroup()
    ActionServer(
        node,
        Fibonacci,
        action_topic,
        _never_ending_goal,
        cancel_callback=lambda _: CancelResponse.REJECT,
        callback_group=group,
    )
    node.create_service(SetBool, service_topic, _never_answered_call, callback_group=group)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    print(READY_LINE, flush=True)
    with contextlib.suppress(KeyboardInterrupt, ExternalShutdownException):
        executor.spin()


if __name__ == '__main__':
    main()
