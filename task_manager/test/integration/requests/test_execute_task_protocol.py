"""/task_manager/execute_task speaks the ROS 2 action protocol exactly (the node serves it
through the action's own services and topics, not rclpy's ActionServer): goal ids, the status
array, CancelGoal's rules and return codes, result retention, as rclpy's ActionClient and a
raw client of the services see them."""

import uuid
from typing import Any

from action_msgs.msg import GoalInfo, GoalStatus, GoalStatusArray
from action_msgs.srv import CancelGoal
from builtin_interfaces.msg import Time
from rclpy.client import Client
from rclpy.qos import qos_profile_action_status_default
from task_manager_msgs.action import ExecuteTask
from test_msgs.action import Fibonacci
from unique_identifier_msgs.msg import UUID

from task_manager.rclpy_tools.server_wait import wait_until_ready
from task_manager.testing.harness import RosHarness, wait_for_future
from task_manager.testing.process import LaunchTaskManager, action_task
from task_manager.testing.servers import ScriptedActionServer

TIMEOUT_SEC = 15.0
SERVICES = '/task_manager/execute_task/_action'


def _goal(order: int, task_id: str) -> ExecuteTask.Goal:
    return ExecuteTask.Goal(task_id=task_id, task_name='fib', task_data=f'{{"order": {order}}}')


def _client(ros: RosHarness, service_type: Any, name: str) -> Client[Any, Any]:
    client: Client[Any, Any] = ros.node.create_client(service_type, f'{SERVICES}/{name}')
    assert wait_until_ready(client.service_is_ready, TIMEOUT_SEC)
    return client


def _cancel(client: Client[Any, Any], goal_id: bytes = bytes(16), stamp: Time | None = None) -> Any:
    request = CancelGoal.Request(
        goal_info=GoalInfo(goal_id=UUID(uuid=list(goal_id)), stamp=stamp or Time())
    )
    return wait_for_future(client.call_async(request), TIMEOUT_SEC, 'cancel')


def test_goal_ids_status_array_results_and_cancel_rules(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    server = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/fib')
    tm = launch_task_manager({'fib': action_task('fib', f'{topic_prefix}/fib', reentrant=True)})
    statuses = ros.record(GoalStatusArray, f'{SERVICES}/status', qos_profile_action_status_default)
    send_goal = _client(ros, ExecuteTask.Impl.SendGoalService, 'send_goal')
    get_result = _client(ros, ExecuteTask.Impl.GetResultService, 'get_result')
    cancel = _client(ros, CancelGoal, 'cancel_goal')

    first = tm.send('fib', {'order': 1}, task_id='first')
    server.wait_for_goals(1, TIMEOUT_SEC)
    first_id = bytes(first.goal_id.uuid)
    statuses.wait_until(
        lambda msgs: (
            msgs
            and any(
                bytes(s.goal_info.goal_id.uuid) == first_id
                and s.status == GoalStatus.STATUS_EXECUTING
                for s in msgs[-1].status_list
            )
        ),
        TIMEOUT_SEC,
        'first EXECUTING in the status array',
    )
    again = wait_for_future(
        send_goal.call_async(
            ExecuteTask.Impl.SendGoalService.Request(
                goal_id=UUID(uuid=list(first_id)), goal=_goal(2, 'again')
            )
        ),
        TIMEOUT_SEC,
        'the same goal id again',
    )
    unknown_result = wait_for_future(
        get_result.call_async(
            ExecuteTask.Impl.GetResultService.Request(goal_id=UUID(uuid=list(uuid.uuid4().bytes)))
        ),
        TIMEOUT_SEC,
        'result of an unknown goal',
    )
    unknown_cancel = _cancel(cancel, uuid.uuid4().bytes)
    second = tm.send('fib', {'order': 2}, task_id='second')
    server.wait_for_goals(2, TIMEOUT_SEC)
    everything = _cancel(cancel)  # zero id and zero stamp: every goal
    first_end, second_end = tm.result_of(first), tm.result_of(second)
    terminated = _cancel(cancel, first_id)
    kept = wait_for_future(
        get_result.call_async(
            ExecuteTask.Impl.GetResultService.Request(goal_id=UUID(uuid=list(first_id)))
        ),
        TIMEOUT_SEC,
        'the kept result',
    )
    nothing_left = _cancel(cancel)

    assert not again.accepted
    assert unknown_result.status == GoalStatus.STATUS_UNKNOWN
    assert (unknown_cancel.return_code, list(unknown_cancel.goals_canceling)) == (
        CancelGoal.Response.ERROR_UNKNOWN_GOAL_ID,
        [],
    )
    assert everything.return_code == CancelGoal.Response.ERROR_NONE
    assert {bytes(g.goal_id.uuid) for g in everything.goals_canceling} == {
        first_id,
        bytes(second.goal_id.uuid),
    }
    for end in (first_end, second_end):
        assert (end.status, end.result.task_status) == (GoalStatus.STATUS_CANCELED, 'CANCELED')
    assert terminated.return_code == CancelGoal.Response.ERROR_GOAL_TERMINATED
    assert (kept.status, kept.result.task_id) == (GoalStatus.STATUS_CANCELED, 'first')
    assert nothing_left.return_code == CancelGoal.Response.ERROR_REJECTED
    statuses.wait_until(
        lambda msgs: {s.status for s in msgs[-1].status_list} == {GoalStatus.STATUS_CANCELED},
        TIMEOUT_SEC,
        'both goals CANCELED in the status array',
    )
    assert first.status == GoalStatus.STATUS_CANCELED  # rclpy's client follows the array


def test_a_stamped_cancel_cancels_the_goals_accepted_until_then(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    server = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/fib')
    tm = launch_task_manager({'fib': action_task('fib', f'{topic_prefix}/fib', reentrant=True)})
    cancel = _client(ros, CancelGoal, 'cancel_goal')
    older = tm.send('fib', {'order': 1}, task_id='older')
    newer = tm.send('fib', {'order': 2}, task_id='newer')
    server.wait_for_goals(2, TIMEOUT_SEC)
    answer = _cancel(cancel, stamp=older.stamp)  # the stamp of its acceptance
    older_end = tm.result_of(older)
    server.goals.items[1].succeed(Fibonacci.Result(sequence=[2]))
    newer_end = tm.result_of(newer)

    assert [bytes(g.goal_id.uuid) for g in answer.goals_canceling] == [bytes(older.goal_id.uuid)]
    assert older_end.result.task_status == 'CANCELED'
    assert (newer_end.status, newer_end.result.task_status) == (GoalStatus.STATUS_SUCCEEDED, 'DONE')
