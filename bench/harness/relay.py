"""The floor of a burst: the least a relay in rclpy does between a client and a task's server.

`python -m bench.harness.relay` serves ExecuteTask (through the action's services, as the node
does) for one task only, the instant Fibonacci goal: it accepts each goal at once, sends the
server a goal, and answers the client's get_result with DONE once the server's result is in.
Nothing else: no task lookup, no JSON, no conflicts, no history, no log line, no active list,
events, status or results topic. It is not a task manager, but what any relay of the same
protocol pays in rclpy: the same hops through one more process, each message taken and sent
by Python. Spun by the node's own executor, the ParkingExecutor (on rclpy's SingleThreadedExecutor
or its EventsExecutor the relay went no faster: docs/benchmarks.md, "The burst's floor"), on a
server of its own (the servers' third twin of the instant Fibonacci server: see
config.DIRECT_FIBONACCI_TOPIC).
"""

from typing import Any

from action_msgs.msg import GoalStatus
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.task import Future
from test_msgs.action import Fibonacci

from bench.harness import config
from bench.harness.lean_action import LeanActionClient, action_service
from bench.harness.processes import spin_child
from task_manager.rclpy_tools.qos import DEEP_RELIABLE
from task_manager.ros import parking_executor
from task_manager.ros.parking_executor import ParkingExecutor
from task_manager_msgs.action import ExecuteTask

RELAY_NODE_NAME = 'task_manager_bench_relay'


class FloorRelay:
    """ExecuteTask in, the instant Fibonacci goal out, DONE back."""

    def __init__(self, node: Node) -> None:
        impl = ExecuteTask.Impl
        group = ReentrantCallbackGroup()
        self._server = LeanActionClient(node, Fibonacci, config.RELAY_FIBONACCI_TOPIC)
        # key: goal id, value: a future of the server's result, until the client asks for it
        self._ends: dict[bytes, Future[Any]] = {}
        # served only once its server is: the bench's wait for the relay then covers both
        if not self._server.wait_for_server(config.CONNECT_TIMEOUT_SEC):
            raise RuntimeError(f'{config.RELAY_FIBONACCI_TOPIC} not served')
        for service, service_type, callback in (
            ('send_goal', impl.SendGoalService, self._on_goal),
            ('get_result', impl.GetResultService, self._on_get_result),
        ):
            node.create_service(
                service_type,
                action_service(config.RELAY_ACTION, service),
                callback,
                qos_profile=DEEP_RELIABLE,
                callback_group=group,
            )

    def _on_goal(self, request: Any, response: Any) -> Any:
        self._ends[bytes(request.goal_id.uuid)] = self._server.send_goal(Fibonacci.Goal(order=0))
        response.accepted = True
        return response

    async def _on_get_result(self, request: Any, response: Any) -> Any:
        ended = self._ends.pop(bytes(request.goal_id.uuid), None)
        if ended is None:
            response.status = GoalStatus.STATUS_UNKNOWN
            return response
        reply = await ended
        succeeded = reply is not None and reply.response is not None
        response.status = GoalStatus.STATUS_SUCCEEDED
        response.result = ExecuteTask.Result(task_status='DONE' if succeeded else 'ERROR')
        return response


def main() -> None:
    parking_executor.install()
    spin_child(RELAY_NODE_NAME, FloorRelay, ParkingExecutor)


if __name__ == '__main__':
    main()
