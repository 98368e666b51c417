"""Conflict rules: single-goal vs reentrant, blocking, cancel_timeout (BEHAVIOUR.md rule 6-7)."""

from action_msgs.msg import GoalStatus
from std_srvs.srv import SetBool
from test_msgs.action import Fibonacci

from task_manager.testing.harness import RosHarness
from task_manager.testing.process import LaunchTaskManager, action_task, service_task
from task_manager.testing.servers import CancelPolicy, ScriptedActionServer, ScriptedService

TIMEOUT_SEC = 15.0


def test_second_goal_of_a_single_goal_task_replaces_the_first(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    server = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/nav')
    tm = launch_task_manager({'nav': action_task('navigate', f'{topic_prefix}/nav')})
    first = tm.send('navigate', {'order': 1}, task_id='first')
    tm.wait_in_progress('first')

    second = tm.send('navigate', {'order': 2}, task_id='second')

    first_response = tm.result_of(first)
    assert first_response.result.task_status == 'CANCELED'
    assert first_response.status == GoalStatus.STATUS_ABORTED  # cancelled by someone else
    tm.wait_in_progress('second')
    goals = server.wait_for_goals(2, TIMEOUT_SEC)
    assert goals[0].cancel_requested.is_set() and not goals[1].cancel_requested.is_set()
    goals[1].succeed()
    assert tm.result_of(second).result.task_status == 'DONE'
    assert tm.wait_result_message('first').task_status == 'CANCELED'


def test_reentrant_goals_run_in_parallel(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    server = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/photo')
    tm = launch_task_manager(
        {'photo': action_task('take_photo', f'{topic_prefix}/photo', reentrant=True)}
    )
    handles = [tm.send('take_photo', {'order': i}, task_id=f'p{i}') for i in range(3)]

    tm.wait_active(lambda tasks: {t for t, s in tasks if s == 'IN_PROGRESS'} >= {'p0', 'p1', 'p2'})

    goals = server.wait_for_goals(3, TIMEOUT_SEC)
    assert not any(g.cancel_requested.is_set() for g in goals)
    for goal in goals:
        goal.succeed()
    assert [tm.result_of(h).result.task_status for h in handles] == ['DONE'] * 3


def test_blocking_task_cancels_the_previous_blocking_task_only(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    nav = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/nav')
    spin = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/spin')
    other = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/other')
    tm = launch_task_manager(
        {
            'nav': action_task('navigate', f'{topic_prefix}/nav', blocking=True),
            'spin': action_task('spin', f'{topic_prefix}/spin', blocking=True),
            'other': action_task('other', f'{topic_prefix}/other'),
        }
    )
    navigate = tm.send('navigate', {'order': 1}, task_id='nav')
    unrelated = tm.send('other', {'order': 1}, task_id='other')
    tm.wait_in_progress('nav')
    tm.wait_in_progress('other')

    spinning = tm.send('spin', {'order': 1}, task_id='spin')

    assert tm.result_of(navigate).result.task_status == 'CANCELED'
    tm.wait_active(
        lambda tasks: ('spin', 'IN_PROGRESS') in tasks and ('other', 'IN_PROGRESS') in tasks
    )
    assert not other.wait_for_goals(1, TIMEOUT_SEC)[0].cancel_requested.is_set()
    assert nav.wait_for_goals(1, TIMEOUT_SEC)[0].cancel_requested.is_set()
    spin.wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    other.wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    assert tm.result_of(spinning).result.task_status == 'DONE'
    assert tm.result_of(unrelated).result.task_status == 'DONE'


def test_new_task_fails_to_start_when_the_conflicting_cancel_times_out(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    stubborn = ScriptedActionServer(
        ros.node, Fibonacci, f'{topic_prefix}/stubborn', cancel_policy=CancelPolicy.IGNORE
    )
    ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/spin')
    tm = launch_task_manager(
        {
            # an integer cancel_timeout is accepted as seconds
            'stubborn': action_task(
                'stubborn', f'{topic_prefix}/stubborn', blocking=True, cancel_timeout=1
            ),
            'spin': action_task('spin', f'{topic_prefix}/spin', blocking=True),
        }
    )
    old = tm.send('stubborn', {'order': 1}, task_id='old')
    tm.wait_in_progress('old')

    new = tm.run('spin', {'order': 1}, task_id='new')

    assert (new.task_status, new.error_code) == ('ERROR', 'task_start_failed')
    goal = stubborn.wait_for_goals(1, TIMEOUT_SEC)[0]
    assert goal.cancel_requested.is_set()
    assert tm.results_for('old') == []  # the old task is still running
    goal.succeed()
    assert tm.result_of(old).result.task_status == 'DONE'


def test_single_goal_service_task_waits_out_its_cancel_timeout(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    service = ScriptedService(ros.node, SetBool, f'{topic_prefix}/set')
    tm = launch_task_manager(
        {'set': service_task('set', f'{topic_prefix}/set', cancel_timeout=0.3)}
    )
    first = tm.send('set', {'data': True}, task_id='first')
    tm.wait_in_progress('first')

    second = tm.run('set', {'data': False}, task_id='second')

    assert (second.task_status, second.error_code) == ('ERROR', 'task_start_failed')
    service.wait_for_calls(1, TIMEOUT_SEC)[0].respond(success=True)
    assert tm.result_of(first).result.task_status == 'DONE'
    assert len(service.calls.items) == 1
