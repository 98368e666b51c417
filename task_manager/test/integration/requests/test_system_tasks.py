"""system/cancel_task, system/stop and system/wait (BEHAVIOUR.md, System tasks)."""

import json

from std_srvs.srv import SetBool
from task_manager_msgs.action import Wait
from test_msgs.action import Fibonacci

from task_manager.rclpy_tools.server_wait import wait_until_ready
from task_manager.testing.harness import RosHarness, wait_for_future
from task_manager.testing.process import LaunchTaskManager, action_task, service_task
from task_manager.testing.servers import ScriptedActionServer, ScriptedService

TIMEOUT_SEC = 15.0


def test_cancel_task_cancels_known_ids_and_counts_unknown_ones_as_cancelled(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    server = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/fib')
    tm = launch_task_manager({'fib': action_task('fib', f'{topic_prefix}/fib', reentrant=True)})
    handles = [tm.send('fib', {'order': i}, task_id=f't{i}') for i in range(2)]
    tm.wait_active(lambda tasks: {'t0', 't1'} <= {t for t, _ in tasks})

    result = tm.run('system/cancel_tasks', {'cancelled_tasks': ['t0', 'ghost']})  # the alias

    assert result.task_status == 'DONE'
    assert json.loads(result.task_result) == {
        'success': True,
        'successful_cancels': ['t0', 'ghost'],
    }
    assert tm.result_of(handles[0]).result.task_status == 'CANCELED'
    goals = server.wait_for_goals(2, TIMEOUT_SEC)
    assert not goals[1].cancel_requested.is_set()
    goals[1].succeed()
    assert tm.result_of(handles[1]).result.task_status == 'DONE'


def test_cancel_task_fails_when_a_service_task_does_not_return_in_time(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    service = ScriptedService(ros.node, SetBool, f'{topic_prefix}/set')
    tm = launch_task_manager(
        {'set': service_task('set', f'{topic_prefix}/set', cancel_timeout=0.3)}
    )
    held = tm.send('set', {'data': True}, task_id='slow')
    tm.wait_in_progress('slow')

    result = tm.run('system/cancel_task', {'cancelled_tasks': ['slow']})

    assert result.task_status == 'ERROR'
    assert json.loads(result.task_result) == {'success': False, 'successful_cancels': []}
    service.wait_for_calls(1, TIMEOUT_SEC)[0].respond(success=True)
    assert tm.result_of(held).result.task_status == 'DONE'


def test_stop_cancels_only_cancel_on_stop_tasks(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    nav = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/nav')
    video = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/video')
    tm = launch_task_manager(
        {
            'nav': action_task('navigate', f'{topic_prefix}/nav', cancel_on_stop=True),
            'video': action_task('record_video', f'{topic_prefix}/video'),
        }
    )
    navigating = tm.send('navigate', {'order': 1}, task_id='nav')
    recording = tm.send('record_video', {'order': 1}, task_id='video')
    tm.wait_active(lambda tasks: {'nav', 'video'} <= {t for t, _ in tasks})

    stop = tm.run('system/stop', '{}')

    assert (stop.task_status, json.loads(stop.task_result)) == ('DONE', {'success': True})
    assert tm.result_of(navigating).result.task_status == 'CANCELED'
    assert not video.wait_for_goals(1, TIMEOUT_SEC)[0].cancel_requested.is_set()
    assert nav.wait_for_goals(1, TIMEOUT_SEC)[0].cancel_requested.is_set()
    video.wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    assert tm.result_of(recording).result.task_status == 'DONE'


def test_wait_with_a_duration_ends_done_or_canceled_if_cancelled_first(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm = launch_task_manager({'fib': action_task('fib', f'{topic_prefix}/fib')})

    short = tm.run('system/wait', {'duration': 0.2})
    long = tm.send('system/wait', {'duration': 60.0}, task_id='long')
    tm.wait_in_progress('long')
    tm.cancel(long)

    assert (short.task_status, short.task_result) == ('DONE', '{}')
    assert tm.result_of(long).result.task_status == 'CANCELED'


def test_endless_wait_goes_on_when_cancelled_and_a_second_wait_pre_empts_the_first(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm = launch_task_manager({'fib': action_task('fib', f'{topic_prefix}/fib')})
    zero = tm.send('system/wait', {'duration': 0.0}, task_id='zero')
    tm.wait_in_progress('zero')
    tm.cancel(zero)
    assert tm.result_of(zero).result.task_status == 'DONE'

    first = tm.send('system/wait', {'duration': -1.0}, task_id='first')
    tm.wait_in_progress('first')
    second = tm.send('system/wait', {'duration': 30.0}, task_id='second')
    tm.wait_in_progress('second')

    assert tm.result_of(first).result.task_status == 'DONE'  # pre-empted: the signal to go on
    tm.run('system/cancel_task', {'cancelled_tasks': ['second']})
    assert tm.result_of(second).result.task_status == 'CANCELED'


def test_wait_publishes_remaining_time_through_its_task_server(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    launch_task_manager(
        {'fib': action_task('fib', f'{topic_prefix}/fib')}, enable_task_servers=True
    )
    client = ros.action_client(Wait, '/task_manager/task/system/wait')
    assert wait_until_ready(client.server_is_ready, TIMEOUT_SEC)
    feedback: list[float] = []

    goal_handle = wait_for_future(
        ros.send_goal(
            client,
            Wait.Goal(duration=1.5),
            lambda m: feedback.append(m.feedback.remaining_time),
        ),
        TIMEOUT_SEC,
        'goal',
    )
    wait_for_future(goal_handle.get_result_async(), TIMEOUT_SEC, 'result')

    assert len(feedback) >= 1
    assert all(0.0 <= remaining <= 1.5 for remaining in feedback)
    assert feedback == sorted(feedback, reverse=True)
    ros.destroy(client)
