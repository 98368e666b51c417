"""Numbers out of their bounds are refused at the door, naming the field and the bound: none
reaches a timer (a timeout of 1e10 s crashed the node's deadline timer after the goal was sent)."""

import json

import pytest
from test_msgs.action import Fibonacci

from task_manager.testing.harness import RosHarness
from task_manager.testing.process import LaunchTaskManager, action_task
from task_manager.testing.servers import ScriptedActionServer

pytestmark = pytest.mark.ros
TIMEOUT_SEC = 15.0


@pytest.mark.parametrize('field', ['timeout_sec', 'queue_timeout_sec', 'feedback_timeout_sec'])
def test_a_timeout_beyond_a_week_is_refused_before_anything_is_sent(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str, field: str
) -> None:
    server = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/drive')
    tm = launch_task_manager({'drive': action_task('drive', f'{topic_prefix}/drive')})

    refused = tm.run_started('drive', {'order': 1}, task_id='far', **{field: 1e10})

    assert (refused.task_status, refused.error_code) == ('ERROR', 'invalid_request')
    assert json.loads(refused.task_result)['error'] == (
        f'{field} must be from 0 to 604800 s, got 10000000000.0'
    )
    assert server.goals.items == []
    # the node serves on, and a week is allowed
    ok = tm.start('drive', {'order': 1}, task_id='week', **{field: 604_800.0})
    server.wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    assert tm.result_of(ok).result.task_status == 'DONE'


@pytest.mark.parametrize(
    ('task_name', 'task_data', 'field'),
    [
        ('system/wait', {'duration': 1e30}, 'duration'),
        ('system/confirm', {'prompt': 'go?', 'timeout_sec': 1e300}, 'timeout_sec'),
    ],
)
def test_a_system_task_duration_beyond_a_week_is_refused_naming_it(
    launch_task_manager: LaunchTaskManager,
    topic_prefix: str,
    task_name: str,
    task_data: dict[str, object],
    field: str,
) -> None:
    tm = launch_task_manager({'drive': action_task('drive', f'{topic_prefix}/drive')})

    refused = tm.run(task_name, task_data)

    assert (refused.task_status, refused.error_code) == ('ERROR', 'task_data_parsing_failed')
    error = json.loads(refused.task_result)['error']
    assert f"field '{field}'" in error and '604800' in error
    assert tm.run('system/wait', {'duration': 0.01}).task_status == 'DONE'


def test_task_data_over_a_mebibyte_is_refused_naming_its_size(
    launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm = launch_task_manager({'drive': action_task('drive', f'{topic_prefix}/drive')})
    data = json.dumps({'order': 1, 'note': 'x' * 1_048_576})

    refused = tm.run('drive', data)

    assert (refused.task_status, refused.error_code) == ('ERROR', 'invalid_request')
    assert json.loads(refused.task_result)['error'] == (
        f'task_data is {len(data)} bytes; at most 1048576 are allowed'
    )


@pytest.mark.parametrize(
    ('task_name', 'task_data', 'field'),
    [
        ('system/cancel_task', {'cancelled_tasks': ['a', 'b', 'a']}, 'cancelled_tasks'),
        ('system/pause', {'task_ids': ['a', 'a']}, 'task_ids'),
        ('system/reprioritize', {'task_ids': ['a'] * 1000, 'priority': 5}, 'task_ids'),
    ],
)
def test_an_id_given_twice_is_refused_naming_it(
    launch_task_manager: LaunchTaskManager,
    topic_prefix: str,
    task_name: str,
    task_data: dict[str, object],
    field: str,
) -> None:
    """Reprioritize with one id 1,000 times added 1,000 decisions to the task per request."""
    tm = launch_task_manager({'drive': action_task('drive', f'{topic_prefix}/drive')})

    refused = tm.run(task_name, task_data)

    assert (refused.task_status, refused.error_code) == ('ERROR', 'task_data_parsing_failed')
    assert json.loads(refused.task_result)['error'] == (
        f"field '{field}': {field} names 'a' more than once; each id at most once"
    )


def test_a_mission_of_more_than_a_thousand_subtasks_is_refused(
    launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm = launch_task_manager({'drive': action_task('drive', f'{topic_prefix}/drive')})
    subtasks = [{'task_name': 'system/wait', 'task_data': '{}'}] * 1001

    refused = tm.run('system/mission', {'subtasks': subtasks})

    assert (refused.task_status, refused.error_code) == ('ERROR', 'task_data_parsing_failed')
    assert 'a mission has at most 1000' in json.loads(refused.task_result)['error']
