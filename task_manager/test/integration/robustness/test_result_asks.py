"""How often the node asks an action server for a goal's result (ActionExecution).

The server's own introspection counts the GetResult requests it receives: rclpy publishes
each on `<action>/_action/get_result/_service_event`.
"""

import json
import threading
import time
from dataclasses import dataclass
from typing import Any

from action_msgs.msg import GoalStatus, GoalStatusArray
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.qos import qos_profile_action_status_default, qos_profile_services_default
from rclpy.service_introspection import ServiceIntrospectionState
from rclpy.task import Future
from service_msgs.msg import ServiceEventInfo
from test_msgs.action import Fibonacci

from task_manager.ros.running.action_runner import RESULT_ASKS_AGAIN_MAX
from task_manager.testing.harness import RosHarness
from task_manager.testing.probe import TaskManagerProbe
from task_manager.testing.process import LaunchTaskManager, action_task
from task_manager.testing.servers import ScriptedActionServer, ScriptedGoal

TIMEOUT_SEC = 15.0
# a fast watch: the asks again (after 1, 2, 4, ... 64 ticks) are over within 2.6 s
WATCH = {'server_check_period': 0.02, 'server_loss_timeout': 30.0}
# a slow one: no ask again within a test
NO_ASK_AGAIN = {'server_check_period': 60.0, 'server_loss_timeout': 300.0}


class ResultRequests:
    """Counts the GetResult requests an action server receives, by goal id."""

    def __init__(self, ros: RosHarness, server: ScriptedActionServer, topic: str) -> None:
        server.server.configure_introspection(
            ros.node.get_clock(), qos_profile_services_default, ServiceIntrospectionState.CONTENTS
        )
        self._by_goal: dict[bytes, int] = {}
        self._changed = threading.Condition()
        self._subscription = ros.node.create_subscription(
            Fibonacci.Impl.GetResultService.Event,
            f'{topic}/_action/get_result/_service_event',
            self._on_event,
            100,
        )

    def _on_event(self, event: Any) -> None:
        if event.info.event_type != ServiceEventInfo.REQUEST_RECEIVED:
            return
        with self._changed:
            for request in event.request:
                goal_id = bytes(request.goal_id.uuid)
                self._by_goal[goal_id] = self._by_goal.get(goal_id, 0) + 1
            self._changed.notify_all()

    def wait_for(self, goal_id: bytes, count: int) -> None:
        with self._changed:
            assert self._changed.wait_for(
                lambda: self._by_goal.get(goal_id, 0) >= count, TIMEOUT_SEC
            ), f'{self._by_goal.get(goal_id, 0)} requests for the goal, not {count}'

    def of(self, goal_id: bytes) -> int:
        with self._changed:
            return self._by_goal.get(goal_id, 0)


@dataclass
class LongGoal:
    """A goal held by its server until the node has asked for its result for the last time."""

    server: ScriptedActionServer
    requests: ResultRequests
    tm: TaskManagerProbe
    handle: Any
    goal: ScriptedGoal
    goal_id: bytes


def _past_its_asks(ros: RosHarness, launch: LaunchTaskManager, topic: str) -> LongGoal:
    server = ScriptedActionServer(ros.node, Fibonacci, topic)
    requests = ResultRequests(ros, server, topic)
    tm = launch({'drive': action_task('drive', topic)}, **WATCH)
    handle = tm.send('drive', {'order': 1}, task_id='long')
    goal = server.wait_for_goals(1, TIMEOUT_SEC)[0]
    goal_id = bytes(goal.goal_handle.goal_id.uuid)
    requests.wait_for(goal_id, 1 + RESULT_ASKS_AGAIN_MAX)
    return LongGoal(server, requests, tm, handle, goal, goal_id)


def test_a_long_goals_result_is_asked_for_a_bounded_number_of_times(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    """The server holds every request it took and answers each as the goal ends: asking on
    for as long as a goal runs would pile up answers (for a thousand goals ending at once,
    more than the node's reader keeps, losing the ones that count)."""
    long = _past_its_asks(ros, launch_task_manager, f'{topic_prefix}/drive')
    # what must not happen takes a while to show: another 128 ticks (2.6 s), in which the
    # node used to ask twice more (each 64 ticks, for as long as the goal ran)
    time.sleep(128 * WATCH['server_check_period'])
    long.goal.succeed()

    assert long.tm.result_of(long.handle).result.task_status == 'DONE'
    assert long.requests.of(long.goal_id) == 1 + RESULT_ASKS_AGAIN_MAX


def test_a_goal_whose_server_restarted_after_the_last_ask_ends_error(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    """Once the node no longer asks, a server that restarts is noticed by its new DDS ids,
    and the result is asked for at once: the new server knows no such goal."""
    topic = f'{topic_prefix}/drive'
    long = _past_its_asks(ros, launch_task_manager, topic)
    ros.destroy(long.server)
    ScriptedActionServer(ros.node, Fibonacci, topic)  # knows no goal

    result = long.tm.result_of(long.handle).result

    assert result.task_status == 'ERROR'
    assert 'no longer knows the goal' in json.loads(result.task_result)['error']


class DecidingServer:
    """An action server made of its services, which accepts a goal only when the test says so
    and answers a result request for a goal it has not accepted STATUS_UNKNOWN at once, as
    rclpy's and rclcpp's servers do (rclpy's own ActionServer may instead hold a result request
    taken in the same turn as its goal until it has decided: not what this test needs)."""

    def __init__(self, ros: RosHarness, topic: str) -> None:
        impl = Fibonacci.Impl
        group = ReentrantCallbackGroup()
        self._ros = ros
        self._decided: Future[None] = Future()
        self._accepted: set[bytes] = set()
        self._ended: Future[None] = Future()
        # (goal id, whether the goal had been accepted) of each result request, in order
        self.result_requests: list[tuple[bytes, bool]] = []
        self._changed = threading.Condition()
        node = ros.node
        self._entities = [
            node.create_service(
                impl.SendGoalService, f'{topic}/_action/send_goal', self._goal, callback_group=group
            ),
            node.create_service(
                impl.GetResultService,
                f'{topic}/_action/get_result',
                self._result,
                callback_group=group,
            ),
            node.create_service(
                impl.CancelGoalService,
                f'{topic}/_action/cancel_goal',
                lambda _request, response: response,
                callback_group=group,
            ),
        ]
        self._status = node.create_publisher(
            GoalStatusArray, f'{topic}/_action/status', qos_profile_action_status_default
        )

    async def _goal(self, request: Any, response: Any) -> Any:
        await self._decided
        self._accepted.add(bytes(request.goal_id.uuid))
        response.accepted = True
        return response

    async def _result(self, request: Any, response: Any) -> Any:
        goal_id = bytes(request.goal_id.uuid)
        with self._changed:
            self.result_requests.append((goal_id, goal_id in self._accepted))
            self._changed.notify_all()
        if goal_id not in self._accepted:
            response.status = GoalStatus.STATUS_UNKNOWN
            return response
        await self._ended
        response.status = GoalStatus.STATUS_SUCCEEDED
        response.result = Fibonacci.Result(sequence=[0, 1, 1])
        return response

    def wait_for_result_requests(self, count: int) -> None:
        with self._changed:
            assert self._changed.wait_for(
                lambda: len(self.result_requests) >= count, TIMEOUT_SEC
            ), f'{len(self.result_requests)} result requests, not {count}'

    def accept(self) -> None:
        self._ros.on_executor(lambda: self._decided.set_result(None))

    def end(self) -> None:
        self._ros.on_executor(lambda: self._ended.set_result(None))

    def destroy(self) -> None:
        for service in self._entities:
            self._ros.node.destroy_service(service)
        self._ros.node.destroy_publisher(self._status)


def test_the_result_is_asked_for_with_the_goal_and_again_once_a_server_that_did_not_know_it_accepts(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    """The node asks for the result right behind the goal, not once the goal is accepted (a
    hop saved on every task): a server that gets that request before it has accepted the goal
    answers it STATUS_UNKNOWN; once it accepts, the result is asked for again, and only that
    answer counts (the task ends DONE with its result, not ERROR)."""
    topic = f'{topic_prefix}/drive'
    server = DecidingServer(ros, topic)
    tm = launch_task_manager({'drive': action_task('drive', topic)}, **NO_ASK_AGAIN)
    handle = tm.send('drive', {'order': 1}, task_id='decided-later')

    server.wait_for_result_requests(1)  # before the server has said whether it takes the goal
    server.accept()
    server.wait_for_result_requests(2)
    server.end()
    result = tm.result_of(handle).result
    server.destroy()

    assert result.task_status == 'DONE'
    assert json.loads(result.task_result) == {'sequence': [0, 1, 1]}
    (first, known_then), (again, known_later) = server.result_requests
    assert first == again and not known_then and known_later
