"""A cancel is never lost: a client's cancel in every window after its goal is accepted.

Each test puts the task in one window on purpose (a server that holds its answer until the
test releases it, a conflict that does not end, a pause) and cancels it there, through
rclpy's own ActionClient (the probe) and through TaskManagerClient:
- the goal just accepted, its task not yet IN_PROGRESS (the cancel sent from the goal
  response's callback, before anything else);
- the task admitted but waiting for a conflicting task to end;
- the goal sent to the task's server, not yet accepted by it;
- a mission between two subtasks;
- a task paused by restart.
"""

import json
from typing import Any

import pytest
from action_msgs.msg import GoalStatus
from rclpy.task import Future
from task_manager_msgs.action import ExecuteTask
from test_msgs.action import Fibonacci

from task_manager.client import TaskManagerClient
from task_manager.rclpy_tools.futures import result_of
from task_manager.rclpy_tools.server_wait import wait_until_ready
from task_manager.testing.harness import RosHarness, wait_for_future
from task_manager.testing.probe import TaskManagerProbe
from task_manager.testing.process import LaunchTaskManager, action_task
from task_manager.testing.servers import CancelPolicy, ScriptedActionServer

TIMEOUT_SEC = 15.0
ATTEMPTS = 3


def _send_and_cancel_at_acceptance(
    tm: TaskManagerProbe, task_name: str, task_data: Any, task_id: str
) -> tuple[Any, Any]:
    """Send an ExecuteTask goal and cancel it as it is accepted (see _cancel_at_acceptance)."""
    goal = ExecuteTask.Goal(
        task_id=task_id, task_name=task_name, source='test', task_data=json.dumps(task_data)
    )
    return _cancel_at_acceptance(tm.ros, tm.client, goal)


def _cancel_at_acceptance(ros: RosHarness, client: Any, goal: Any) -> tuple[Any, Any]:
    """Send a goal and cancel it from the goal response's callback, on the executor thread,
    before anything else runs; returns (goal handle, cancel response)."""
    cancelled: Future[Any] = Future()

    def on_response(response: Future[Any]) -> None:
        handle = result_of(response)
        assert handle.accepted
        handle.cancel_goal_async().add_done_callback(
            lambda done: cancelled.set_result((handle, done.result()))
        )

    ros.send_goal(client, goal).add_done_callback(on_response)
    result: tuple[Any, Any] = wait_for_future(cancelled, TIMEOUT_SEC, 'cancel at acceptance')
    return result


def _assert_cancelled_by_its_client(tm: TaskManagerProbe, handle: Any, cancel: Any) -> None:
    assert len(cancel.goals_canceling) == 1, 'the cancel was not accepted'
    response = tm.result_of(handle)
    assert (response.status, response.result.task_status) == (
        GoalStatus.STATUS_CANCELED,
        'CANCELED',
    ), response.result
    published = tm.wait_result_message(response.result.task_id)
    assert published.task_status == 'CANCELED'


@pytest.fixture
def tm(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> tuple[TaskManagerProbe, ScriptedActionServer]:
    """`fib` (an action whose goals run until the test ends them), `drive` (the same,
    blocking) and the system tasks."""
    server = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/fib')
    probe = launch_task_manager(
        {
            'fib': action_task('fib', f'{topic_prefix}/fib'),
            'drive': action_task('drive', f'{topic_prefix}/fib', blocking=True),
        }
    )
    return probe, server


@pytest.mark.parametrize(
    ('task_name', 'task_data'),
    [
        ('fib', {'order': 10}),
        ('drive', {'order': 10}),
        ('system/wait', {'duration': 60.0}),
        (
            'system/mission',
            {'subtasks': [{'task_name': 'system/wait', 'task_data': '{"duration": 60.0}'}]},
        ),
    ],
)
def test_a_cancel_sent_as_the_goal_is_accepted_cancels_the_task(
    tm: tuple[TaskManagerProbe, ScriptedActionServer], task_name: str, task_data: Any
) -> None:
    probe, server = tm
    for attempt in range(ATTEMPTS):
        handle, cancel = _send_and_cancel_at_acceptance(
            probe, task_name, task_data, f'at-acceptance-{attempt}'
        )
        _assert_cancelled_by_its_client(probe, handle, cancel)
    # a goal that reached the server before the cancel was cancelled there too
    for goal in server.goals.items:
        assert goal.cancel_requested.is_set()
        assert goal.ended.wait(TIMEOUT_SEC)


def test_a_cancel_sent_as_a_task_servers_goal_is_accepted_cancels_the_task(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    server = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/fib')
    probe = launch_task_manager(
        {'fib': action_task('math/fib', f'{topic_prefix}/fib')}, enable_task_servers=True
    )
    client = ros.action_client(Fibonacci, '/task_manager/task/math/fib')
    assert wait_until_ready(client.server_is_ready, TIMEOUT_SEC)
    for _ in range(ATTEMPTS):
        handle, cancel = _cancel_at_acceptance(ros, client, Fibonacci.Goal(order=6))

        assert len(cancel.goals_canceling) == 1, 'the cancel was not accepted'
        response = wait_for_future(handle.get_result_async(), TIMEOUT_SEC, 'result')
        assert response.status == GoalStatus.STATUS_CANCELED
    ended = probe.results.wait_until(
        lambda msgs: (
            len(ours := [m for m in msgs if m.source == 'task_server']) >= ATTEMPTS and ours
        ),
        TIMEOUT_SEC,
        'results',
    )
    assert [m.task_status for m in ended] == ['CANCELED'] * ATTEMPTS
    for goal in server.goals.items:
        assert goal.cancel_requested.is_set()
    ros.destroy(client)


def test_a_cancel_while_the_task_waits_for_a_conflicting_task_to_end(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    slow = ScriptedActionServer(
        ros.node, Fibonacci, f'{topic_prefix}/slow', cancel_policy=CancelPolicy.IGNORE
    )
    fast = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/fast')
    probe = launch_task_manager(
        {
            'slow': action_task('slow', f'{topic_prefix}/slow', blocking=True, cancel_timeout=30),
            'fast': action_task('fast', f'{topic_prefix}/fast', blocking=True),
        }
    )
    probe.send('slow', {'order': 1}, task_id='slow-1')
    stuck = slow.wait_for_goals(1, TIMEOUT_SEC)[0]
    waiting = probe.send('fast', {'order': 2}, task_id='fast-1')
    assert stuck.cancel_requested.wait(TIMEOUT_SEC)  # fast-1 now waits for slow-1 to end

    cancel = probe.cancel(waiting)

    _assert_cancelled_by_its_client(probe, waiting, cancel)
    assert fast.goals.items == []  # it never started
    stuck.succeed()
    assert probe.wait_result_message('slow-1').task_status == 'DONE'


@pytest.mark.parametrize('server_answer', ['accept', 'reject'])
def test_a_cancel_while_the_task_server_has_not_yet_accepted_the_goal(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str, server_answer: str
) -> None:
    server = ScriptedActionServer(
        ros.node, Fibonacci, f'{topic_prefix}/fib', hold_goal_requests=True
    )
    probe = launch_task_manager({'fib': action_task('fib', f'{topic_prefix}/fib')})
    handle = probe.send('fib', {'order': 3}, task_id='held-1')
    held = server.wait_for_held(1, TIMEOUT_SEC)[0]

    cancel = probe.cancel(handle)  # answered by the Task Manager before the server answers
    getattr(held, server_answer)()

    _assert_cancelled_by_its_client(probe, handle, cancel)
    if server_answer == 'accept':  # the goal the server accepted late was cancelled there
        goal = server.wait_for_goals(1, TIMEOUT_SEC)[0]
        assert goal.cancel_requested.is_set() and goal.ended.wait(TIMEOUT_SEC)


def test_a_cancel_of_a_mission_between_its_subtasks(
    tm: tuple[TaskManagerProbe, ScriptedActionServer],
) -> None:
    probe, server = tm
    mission = probe.send(
        'system/mission',
        {
            'subtasks': [
                {'task_name': 'fib', 'task_data': '{"order": 1}', 'task_id': 'first'},
                {'task_name': 'fib', 'task_data': '{"order": 2}', 'task_id': 'second'},
            ]
        },
        task_id='mission-1',
    )
    first = server.wait_for_goals(1, TIMEOUT_SEC)[0]
    assert probe.run('system/pause', {'task_ids': ['mission-1']}).task_status == 'DONE'
    first.succeed()
    assert probe.wait_result_message('first').task_status == 'DONE'  # the mission is between

    cancel = probe.cancel(mission)

    _assert_cancelled_by_its_client(probe, mission, cancel)
    rows = json.loads(probe.wait_result_message('mission-1').task_result)['mission_results']
    assert [(r['task_id'], r['task_status']) for r in rows] == [
        ('first', 'DONE'),
        ('second', 'RECEIVED'),
    ]
    assert len(server.goals.items) == 1  # the second subtask never started


def test_a_cancel_of_a_paused_task(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    server = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/nav')
    probe = launch_task_manager(
        {'nav': action_task('navigate', f'{topic_prefix}/nav', pause='restart')}
    )
    handle = probe.send('navigate', {'order': 4}, task_id='drive-1')
    server.wait_for_goals(1, TIMEOUT_SEC)
    # the server's goal callback runs before the node has its accept: only then is it running
    probe.wait_in_progress('drive-1')
    assert probe.run('system/pause', {'task_ids': ['drive-1']}).task_status == 'DONE'
    probe.wait_active(lambda tasks: ('drive-1', 'PAUSED') in tasks, 'drive-1 PAUSED')

    cancel = probe.cancel(handle)

    _assert_cancelled_by_its_client(probe, handle, cancel)
    assert len(server.goals.items) == 1  # not restarted


def test_the_python_client_cancels_a_task_it_just_started(
    tm: tuple[TaskManagerProbe, ScriptedActionServer],
) -> None:
    _, server = tm
    with TaskManagerClient(node_name='cancel_window_client') as client:
        client.wait_until_available()
        for attempt in range(ATTEMPTS):
            for task_name, data in (('fib', {'order': 5}), ('system/wait', {'duration': 60.0})):
                handle = client.start_task(task_name, data, task_id=f'{task_name}-{attempt}')
                assert handle.cancel(), f'the cancel of {handle.task_id} was not accepted'
                result = handle.result(TIMEOUT_SEC)
                assert result.status == 'CANCELED', result
    for goal in server.goals.items:
        assert goal.cancel_requested.is_set()
