"""/task_manager/execute_task: ids, errors, end statuses, cancels (BEHAVIOUR.md rules 1-10)."""

import json
import re
import uuid

from action_msgs.msg import GoalStatus
from std_srvs.srv import SetBool
from test_msgs.action import Fibonacci

from task_manager.testing.harness import RosHarness
from task_manager.testing.process import LaunchTaskManager, action_task, service_task
from task_manager.testing.servers import ScriptedActionServer, ScriptedService

TIMEOUT_SEC = 15.0


def _instant_fibonacci(ros: RosHarness, topic: str) -> ScriptedActionServer:
    return ScriptedActionServer(
        ros.node,
        Fibonacci,
        topic,
        on_goal=lambda goal: goal.succeed(Fibonacci.Result(sequence=[0, 1, 1])),
    )


def test_empty_id_gets_a_uuid_and_the_result_carries_it(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    server = _instant_fibonacci(ros, f'{topic_prefix}/fib')
    tm = launch_task_manager({'fib': action_task('nav/fib', f'{topic_prefix}/fib')})

    generated = tm.run('nav/fib', {'order': 3}, source='CLOUD')
    given = tm.run('nav/fib', {'order': 2}, task_id='my-id')

    assert uuid.UUID(generated.task_id).version == 4
    assert given.task_id == 'my-id'
    assert (generated.task_status, generated.error_code) == ('DONE', '')
    assert json.loads(generated.task_result) == {'sequence': [0, 1, 1]}
    assert [g.request.order for g in server.wait_for_goals(2, TIMEOUT_SEC)] == [3, 2]
    published = tm.wait_result_message(generated.task_id)
    assert (published.task_name, published.task_status, published.source) == (
        'nav/fib',
        'DONE',
        'CLOUD',
    )
    assert json.loads(published.task_result) == {'sequence': [0, 1, 1]}


def test_unknown_task_is_an_error_whose_result_lists_the_declared_tasks(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm = launch_task_manager({'fib': action_task('fib', f'{topic_prefix}/fib')})

    handle = tm.send('no/such_task', {'order': 1}, task_id='u1')
    response = tm.result_of(handle)

    assert (response.result.task_status, response.result.error_code) == ('ERROR', 'unknown_task')
    assert json.loads(response.result.task_result) == {
        'error': "unknown task 'no/such_task'; declared tasks: fib, system/cancel_task, "
        'system/cancel_tasks, system/confirm, system/enable_schedule, system/mission, '
        'system/pause, system/reprioritize, system/resume, system/schedule, system/stop, '
        'system/unschedule, system/wait'
    }
    assert response.status == GoalStatus.STATUS_ABORTED
    published = tm.wait_result_message('u1')
    assert (published.task_status, published.error_code, published.task_name) == (
        'ERROR',
        'unknown_task',
        'no/such_task',
    )
    assert published.task_result == response.result.task_result


BAD_TASK_DATA = [
    '',
    '   ',
    'not json',
    '{"order": 1',
    '[]',
    'null',
    '1',
    '"x"',
    'true',
    '{"order": "abc"}',
    '{"order": 1.5}',
    '{"order": true}',
    '{"order": null}',
    '{"order": [1]}',
    '{"order": 2147483648}',
    '{}',
    '{"ordr": 3}',
]


def test_bad_task_data_is_rejected_and_nothing_reaches_the_server(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    server = _instant_fibonacci(ros, f'{topic_prefix}/fib')
    tm = launch_task_manager({'fib': action_task('fib', f'{topic_prefix}/fib')})

    outcomes = {data: tm.run('fib', data) for data in BAD_TASK_DATA}
    accepted = tm.run('fib', '{"order": 2, "unknown_key": 1}')

    for data, result in outcomes.items():
        assert (result.task_status, result.error_code) == ('ERROR', 'task_data_parsing_failed')
        assert list(json.loads(result.task_result)) == ['error'], data
    reasons = {data: json.loads(outcomes[data].task_result)['error'] for data in outcomes}
    assert reasons['{"order": "abc"}'] == "field 'order': expected int32, got 'abc' (str)"
    assert reasons['{"order": 2147483648}'] == (
        "field 'order': 2147483648 is out of range for int32 [-2147483648, 2147483647]"
    )
    assert reasons['[]'].startswith('task_data: ') and 'object' in reasons['[]']
    # The log says the same as the caller is told.
    abc_reason = reasons['{"order": "abc"}']
    tm.process.wait_for_log(re.escape(f'rejected, task_data_parsing_failed: {abc_reason}'), 5.0)
    assert accepted.task_status == 'DONE'
    assert [g.request.order for g in server.wait_for_goals(1, TIMEOUT_SEC)] == [2]
    assert len(server.goals.items) == 1


def test_duplicate_active_id_is_rejected_and_the_active_task_is_untouched(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    server = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/fib')
    tm = launch_task_manager({'fib': action_task('fib', f'{topic_prefix}/fib', reentrant=True)})
    first = tm.send('fib', {'order': 1}, task_id='dup')
    tm.wait_in_progress('dup')

    duplicate = tm.run('fib', {'order': 2}, task_id='dup')

    assert (duplicate.task_status, duplicate.error_code) == ('ERROR', 'duplicate_id')
    assert json.loads(duplicate.task_result) == {
        'error': "task id 'dup' is in use by an active task; "
        'an id may be used again once its task has ended'
    }
    goal = server.wait_for_goals(1, TIMEOUT_SEC)[0]
    assert not goal.cancel_requested.is_set() and len(server.goals.items) == 1
    goal.succeed()
    assert tm.result_of(first).result.task_status == 'DONE'
    server_after = tm.send('fib', {'order': 3}, task_id='dup')
    server.wait_for_goals(2, TIMEOUT_SEC)[1].succeed()
    assert tm.result_of(server_after).result.task_status == 'DONE'


def test_end_status_follows_how_the_action_server_ended_the_goal(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    server = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/fib')
    tm = launch_task_manager({'fib': action_task('fib', f'{topic_prefix}/fib', reentrant=True)})
    succeeded, aborted = tm.send('fib', {'order': 1}), tm.send('fib', {'order': 2})
    goals = {g.request.order: g for g in server.wait_for_goals(2, TIMEOUT_SEC)}

    goals[1].succeed(Fibonacci.Result(sequence=[7]))
    goals[2].abort(Fibonacci.Result(sequence=[9]))

    done, error = tm.result_of(succeeded), tm.result_of(aborted)
    assert (done.status, done.result.task_status) == (GoalStatus.STATUS_SUCCEEDED, 'DONE')
    assert json.loads(done.result.task_result) == {'sequence': [7]}
    assert (error.status, error.result.task_status) == (GoalStatus.STATUS_ABORTED, 'ERROR')
    assert json.loads(error.result.task_result) == {'sequence': [9]}


def test_client_cancel_ends_the_task_canceled_and_the_goal_canceled(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    server = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/fib')
    recorder = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/rec')
    tm = launch_task_manager(
        {
            'fib': action_task('fib', f'{topic_prefix}/fib'),
            'rec': action_task(
                'record_video', f'{topic_prefix}/rec', cancel_reported_as_success=True
            ),
        }
    )
    plain = tm.send('fib', {'order': 1}, task_id='plain')
    video = tm.send('record_video', {'order': 1}, task_id='video')
    tm.wait_in_progress('plain')
    tm.wait_in_progress('video')

    tm.cancel(plain)
    tm.cancel(video)

    plain_response, video_response = tm.result_of(plain), tm.result_of(video)
    assert server.wait_for_goals(1, TIMEOUT_SEC)[0].cancel_requested.is_set()
    assert recorder.wait_for_goals(1, TIMEOUT_SEC)[0].cancel_requested.is_set()
    assert plain_response.status == GoalStatus.STATUS_CANCELED
    assert plain_response.result.task_status == 'CANCELED'
    assert video_response.result.task_status == 'DONE'
    assert tm.wait_result_message('video').task_status == 'DONE'


def test_service_task_done_or_error_by_its_success_field(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    ScriptedService(
        ros.node,
        SetBool,
        f'{topic_prefix}/set',
        on_call=lambda call: call.respond(success=call.request.data, message='echo'),
    )
    tm = launch_task_manager(
        {
            'plain': service_task('plain', f'{topic_prefix}/set'),
            'checked': service_task(
                'checked', f'{topic_prefix}/set', service_success_field='success'
            ),
        }
    )

    plain_false = tm.run('plain', {'data': False})
    checked_true = tm.run('checked', {'data': True})
    checked_false = tm.run('checked', {'data': False})

    assert plain_false.task_status == 'DONE'
    assert json.loads(plain_false.task_result) == {'success': False, 'message': 'echo'}
    assert checked_true.task_status == 'DONE'
    assert (checked_false.task_status, checked_false.error_code) == ('ERROR', '')


def test_client_cancel_of_a_service_task_that_does_not_return_fails_but_the_task_goes_on(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    service = ScriptedService(ros.node, SetBool, f'{topic_prefix}/set')
    tm = launch_task_manager(
        {'slow': service_task('slow', f'{topic_prefix}/set', cancel_timeout=0.5)}
    )
    handle = tm.send('slow', {'data': True}, task_id='slow-1')
    tm.wait_in_progress('slow-1')

    tm.cancel(handle)

    response = tm.result_of(handle)
    assert (response.result.task_status, response.result.error_code) == (
        'ERROR',
        'task_cancel_failed',
    )
    assert 'still running' in json.loads(response.result.task_result)['error']
    assert response.status == GoalStatus.STATUS_ABORTED
    # The call goes on: still in progress, and no result published for it yet.
    latest_active = tm.active.snapshot()[-1]
    assert [(t.task_id, t.task_status) for t in latest_active.active_tasks] == [
        ('slow-1', 'IN_PROGRESS')
    ]
    assert tm.results_for('slow-1') == []

    service.wait_for_calls(1, TIMEOUT_SEC)[0].respond(success=True)

    published = tm.wait_result_message('slow-1')
    assert (published.task_status, published.error_code) == ('DONE', '')
    assert json.loads(published.task_result)['success'] is True
    tm.wait_active(lambda tasks: tasks == [], 'slow-1 gone from the active tasks')
    assert len(tm.results_for('slow-1')) == 1


def test_missing_or_rejecting_server_fails_the_start(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    rejecting = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/rej', accept_goals=False)
    tm = launch_task_manager(
        {
            'missing': action_task('missing', f'{topic_prefix}/nobody'),
            'missing_srv': service_task('missing_srv', f'{topic_prefix}/nobody_srv'),
            'rejecting': action_task('rejecting', f'{topic_prefix}/rej'),
        },
        server_wait_timeout=0.5,
    )

    reasons = {}
    for name in ('missing', 'missing_srv', 'rejecting'):
        result = tm.run(name, {'order': 1} if name != 'missing_srv' else {'data': True})
        assert (result.task_status, result.error_code) == ('ERROR', 'task_start_failed'), name
        reasons[name] = json.loads(result.task_result)['error']
    assert reasons == {
        'missing': f'action server {topic_prefix}/nobody is not available',
        'missing_srv': f'service {topic_prefix}/nobody_srv is not available',
        'rejecting': f'action server {topic_prefix}/rej rejected the goal',
    }
    assert len(rejecting.rejected.items) == 1


def test_unrelated_task_starts_while_another_tasks_server_is_missing(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    _instant_fibonacci(ros, f'{topic_prefix}/fib')
    tm = launch_task_manager(
        {
            'missing': action_task('missing', f'{topic_prefix}/nobody', blocking=True),
            'fib': action_task('fib', f'{topic_prefix}/fib'),
        },
        server_wait_timeout=5.0,
    )
    waiting = tm.send('missing', {'order': 1}, task_id='waits-for-server')

    unrelated = tm.run('fib', {'order': 1})

    assert unrelated.task_status == 'DONE'
    assert tm.results_for('waits-for-server') == []  # still waiting for its server
    assert tm.result_of(waiting).result.error_code == 'task_start_failed'


def test_control_characters_and_overlong_names_are_refused_and_logged_safely(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    server = _instant_fibonacci(ros, f'{topic_prefix}/fib')
    tm = launch_task_manager({'fib': action_task('fib', f'{topic_prefix}/fib')})
    forged = 'id\n[INFO] [0.0] [task_manager]: forged'

    refused = {
        'newline id': tm.run('fib', {'order': 1}, task_id=forged),
        'reversed name': tm.run('fib\u202e', {'order': 1}, task_id='rtl'),
        'escape in source': tm.run('fib', {'order': 1}, task_id='esc', source='CLI\x1b[2J'),
        'long id': tm.run('fib', {'order': 1}, task_id='x' * 100_000),
    }
    accepted = tm.run('fib', {'order': 1}, task_id='plain', source='Voice control')

    for case, result in refused.items():
        assert (result.task_status, result.error_code) == ('ERROR', 'invalid_request'), case
    reasons = {case: json.loads(r.task_result)['error'] for case, r in refused.items()}
    assert reasons['newline id'].startswith('task_id contains the character U+000A at position 2')
    assert reasons['reversed name'].startswith('task_name contains the character U+202E')
    assert reasons['escape in source'].startswith('source contains the character U+001B')
    assert reasons['long id'] == 'task_id has 100000 characters; at most 256 are allowed'
    assert accepted.task_status == 'DONE'
    assert [g.request.order for g in server.wait_for_goals(1, TIMEOUT_SEC)] == [1]
    tm.process.wait_for_log(r'task plain \(fib\).*ended DONE', TIMEOUT_SEC)
    log = tm.process.log_lines
    assert not any('forged' in line and line.startswith('[INFO] [0.0]') for line in log)
    assert any('id\\u000a[INFO] [0.0] [task_manager]: forged' in line for line in log)
    assert max(len(line) for line in log) < 2000  # the 100,000-character id is cut
