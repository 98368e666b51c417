"""How often the node asks an action server for a goal's result (ActionExecution).

The server's own introspection counts the GetResult requests it receives: rclpy publishes
each on `<action>/_action/get_result/_service_event`.
"""

import json
import threading
import time
from dataclasses import dataclass
from typing import Any

from rclpy.qos import qos_profile_services_default
from rclpy.service_introspection import ServiceIntrospectionState
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

    def wait_for_any(self, count: int) -> None:
        """Wait until the server has received `count` requests, for whichever goals."""
        with self._changed:
            assert self._changed.wait_for(
                lambda: sum(self._by_goal.values()) >= count, TIMEOUT_SEC
            ), f'{sum(self._by_goal.values())} requests, not {count}'


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


def test_the_result_is_asked_for_with_the_goal_and_again_once_a_server_that_did_not_know_it_accepts(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    """The node asks for the result right behind the goal, not once the goal is accepted (a
    hop saved on every task): here the server holds the goal for a decision, so it answers
    that request STATUS_UNKNOWN; once it accepts, the result is asked for again, and only
    that answer counts (the task ends DONE with its result, not ERROR)."""
    topic = f'{topic_prefix}/drive'
    server = ScriptedActionServer(ros.node, Fibonacci, topic, hold_goal_requests=True)
    requests = ResultRequests(ros, server, topic)
    tm = launch_task_manager({'drive': action_task('drive', topic)}, **NO_ASK_AGAIN)
    handle = tm.send('drive', {'order': 1}, task_id='decided-later')
    held = server.wait_for_held(1, TIMEOUT_SEC)[0]

    requests.wait_for_any(1)  # before the server has said whether it takes the goal
    held.accept()
    goal = server.wait_for_goals(1, TIMEOUT_SEC)[0]
    goal.succeed(Fibonacci.Result(sequence=[0, 1, 1]))
    result = tm.result_of(handle).result

    assert result.task_status == 'DONE'
    assert json.loads(result.task_result) == {'sequence': [0, 1, 1]}
    assert requests.of(bytes(goal.goal_handle.goal_id.uuid)) == 2
