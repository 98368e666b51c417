"""system/mission: subtasks in order, skipping, cancels and pre-emption (BEHAVIOUR.md)."""

import json
from typing import Any

from action_msgs.msg import GoalStatus
from test_msgs.action import Fibonacci

from task_manager.testing.harness import RosHarness
from task_manager.testing.process import LaunchTaskManager, action_task
from task_manager.testing.servers import ScriptedActionServer, ScriptedGoal

TIMEOUT_SEC = 15.0
FAIL, HOLD = 99, 50  # Fibonacci orders the scripted servers abort / keep running


def _decide(goal: ScriptedGoal) -> None:
    if goal.request.order == FAIL:
        goal.abort()
    elif goal.request.order < HOLD:
        goal.succeed(Fibonacci.Result(sequence=[goal.request.order]))


def _subtask(
    name: str, order: int, task_id: str = '', allow_skipping: bool = False
) -> dict[str, Any]:
    return {
        'task_id': task_id,
        'task_name': name,
        'task_data': json.dumps({'order': order}),
        'allow_skipping': allow_skipping,
    }


def _rows(result: Any) -> list[tuple[str, str, bool]]:
    return [
        (r['task_id'], r['task_status'], r['skipped'])
        for r in json.loads(result.task_result)['mission_results']
    ]


def _launch(ros: RosHarness, launch: LaunchTaskManager, prefix: str) -> tuple[Any, Any, Any]:
    nav = ScriptedActionServer(ros.node, Fibonacci, f'{prefix}/nav', on_goal=_decide)
    photo = ScriptedActionServer(ros.node, Fibonacci, f'{prefix}/photo', on_goal=_decide)
    tm = launch(
        {
            'nav': action_task('navigate', f'{prefix}/nav', blocking=True, cancel_on_stop=True),
            'photo': action_task('take_photo', f'{prefix}/photo', reentrant=True),
            'spin': action_task('spin', f'{prefix}/nav', blocking=True),
        }
    )
    return tm, nav, photo


def test_mission_runs_its_subtasks_in_order_as_independent_tasks(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, nav, photo = _launch(ros, launch_task_manager, topic_prefix)
    subtasks = [
        _subtask('navigate', 1, 'n1'),
        _subtask('take_photo', 2),
        _subtask('navigate', 3, 'n2'),
    ]

    result = tm.run('system/mission', {'subtasks': subtasks}, task_id='m1', source='CLOUD')

    assert (result.task_status, result.error_code) == ('DONE', '')
    rows = _rows(result)
    assert [(r[1], r[2]) for r in rows] == [('DONE', False)] * 3
    assert rows[0][0] == 'n1' and rows[2][0] == 'n2' and rows[1][0]  # empty id generated
    assert [g.request.order for g in nav.wait_for_goals(2, TIMEOUT_SEC)] == [1, 3]
    assert [g.request.order for g in photo.wait_for_goals(1, TIMEOUT_SEC)] == [2]
    for task_id, _, _ in rows:
        published = tm.wait_result_message(task_id)
        assert (published.task_status, published.source) == ('DONE', 'Mission')
    mission = tm.wait_result_message('m1')
    assert (mission.task_name, mission.task_status, mission.source) == (
        'system/mission',
        'DONE',
        'CLOUD',
    )
    # each of them on the active list at least once (a list may come after the results: each
    # topic is its own stream)
    every_id = {'m1', 'n1', 'n2', rows[1][0]}
    tm.active.wait_until(
        lambda lists: every_id <= {t.task_id for m in lists for t in m.active_tasks},
        TIMEOUT_SEC,
        'the mission and its three subtasks on the active lists',
    )


def test_a_subtask_s_task_data_may_be_a_json_object_as_a_mission_file_writes_it(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, nav, photo = _launch(ros, launch_task_manager, topic_prefix)
    subtasks = [
        {'task_name': 'navigate', 'task_data': {'order': 1}},
        {'task_name': 'take_photo', 'task_data': json.dumps({'order': 2})},  # text, as before
    ]

    result = tm.run('system/mission', {'subtasks': subtasks}, task_id='m-objects')

    assert (result.task_status, result.error_code) == ('DONE', '')
    assert [g.request.order for g in nav.wait_for_goals(1, TIMEOUT_SEC)] == [1]
    assert [g.request.order for g in photo.wait_for_goals(1, TIMEOUT_SEC)] == [2]


def test_failing_subtask_ends_the_mission_and_later_ones_never_start(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, nav, _photo = _launch(ros, launch_task_manager, topic_prefix)
    subtasks = [
        _subtask('navigate', 1, 'a'),
        _subtask('take_photo', FAIL, 'b'),
        _subtask('navigate', 3, 'c'),
    ]

    result = tm.run('system/mission', {'subtasks': subtasks})

    assert result.task_status == 'ERROR'
    assert _rows(result) == [('a', 'DONE', False), ('b', 'ERROR', False), ('c', 'RECEIVED', False)]
    tm.run('take_photo', {'order': 1}, task_id='sentinel')
    tm.wait_result_message('sentinel')
    assert tm.results_for('c') == []
    assert [g.request.order for g in nav.goals.items] == [1]


def test_skippable_failing_subtask_is_skipped_and_the_mission_goes_on(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, _nav, _ = _launch(ros, launch_task_manager, topic_prefix)
    subtasks = [
        _subtask('navigate', 1, 'a'),
        _subtask('take_photo', FAIL, 'b', allow_skipping=True),
        _subtask('navigate', 3, 'c'),
    ]

    result = tm.run('system/mission', {'subtasks': subtasks})

    assert result.task_status == 'DONE'
    assert _rows(result) == [('a', 'DONE', False), ('b', 'ERROR', True), ('c', 'DONE', False)]
    assert tm.wait_result_message('b').task_status == 'ERROR'


def test_invalid_unskippable_subtask_fails_the_mission_before_anything_runs_with_its_rows(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, nav, _ = _launch(ros, launch_task_manager, topic_prefix)
    bad_data = {'task_id': 'bad', 'task_name': 'navigate', 'task_data': '{"order": "x"}'}

    unknown = tm.run(
        'system/mission', {'subtasks': [_subtask('navigate', 1, 'n'), _subtask('fly', 1, 'f')]}
    )
    malformed = tm.run('system/mission', {'subtasks': [_subtask('navigate', 1, 'm'), bad_data]})
    nested = tm.run(
        'system/mission',
        {'subtasks': [{'task_id': 'inner', 'task_name': 'system/mission', 'task_data': '{}'}]},
    )

    for result in (unknown, malformed, nested):
        assert (result.task_status, result.error_code) == ('ERROR', 'task_data_parsing_failed')
    assert _rows(unknown) == [('n', 'RECEIVED', False), ('f', 'ERROR', False)]
    assert json.loads(unknown.task_result)['error'].startswith(
        "field 'subtasks[1].task_name': unknown task 'fly'; declared tasks: navigate, spin, "
    )
    assert _rows(malformed) == [('m', 'RECEIVED', False), ('bad', 'ERROR', False)]
    assert json.loads(malformed.task_result)['error'] == (
        "field 'subtasks[1].task_data': field 'order': expected int32, got 'x' (str)"
    )
    assert _rows(nested) == [('inner', 'ERROR', False)]
    assert 'a mission cannot contain a mission' in json.loads(nested.task_result)['error']
    # Each invalid subtask has its own result, as any refused request; the others never ran.
    for task_id, code in (('f', 'unknown_task'), ('bad', 'task_data_parsing_failed')):
        published = tm.wait_result_message(task_id)
        assert (published.task_status, published.error_code, published.source) == (
            'ERROR',
            code,
            'Mission',
        )
        assert json.loads(published.task_result)['error']
    assert tm.results_for('n') == [] and tm.results_for('m') == []
    assert nav.goals.items == []


def test_malformed_mission_is_refused_without_rows(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, nav, _ = _launch(ros, launch_task_manager, topic_prefix)

    not_a_list = tm.run('system/mission', '{"subtasks": 5}')
    nameless = tm.run(
        'system/mission', {'subtasks': [_subtask('navigate', 1), _subtask('', 1, 'x')]}
    )
    twice = tm.run(
        'system/mission', {'subtasks': [_subtask('navigate', 1, 'a'), _subtask('navigate', 2, 'a')]}
    )

    for result in (not_a_list, nameless, twice):
        assert (result.task_status, result.error_code) == ('ERROR', 'task_data_parsing_failed')
        assert list(json.loads(result.task_result)) == ['error']
    assert json.loads(nameless.task_result)['error'] == (
        "field 'subtasks[1].task_name': every subtask needs a name"
    )
    assert "given more than once: ['a']" in json.loads(twice.task_result)['error']
    assert tm.results_for('x') == [] and nav.goals.items == []


def test_invalid_skippable_subtasks_are_skipped_when_their_turn_comes(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, nav, _ = _launch(ros, launch_task_manager, topic_prefix)
    subtasks = [
        _subtask('navigate', 1, 'a'),
        _subtask('fly', 1, 'b', allow_skipping=True),
        {
            'task_id': 'c',
            'task_name': 'take_photo',
            'task_data': '{"order": "x"}',
            'allow_skipping': True,
        },
        _subtask('navigate', 3, 'd'),
    ]

    result = tm.run('system/mission', {'subtasks': subtasks}, task_id='m')

    assert (result.task_status, result.error_code) == ('DONE', '')
    assert _rows(result) == [
        ('a', 'DONE', False),
        ('b', 'ERROR', True),
        ('c', 'ERROR', True),
        ('d', 'DONE', False),
    ]
    assert [g.request.order for g in nav.wait_for_goals(2, TIMEOUT_SEC)] == [1, 3]
    unknown, bad_data = tm.wait_result_message('b'), tm.wait_result_message('c')
    assert (unknown.error_code, unknown.source) == ('unknown_task', 'Mission')
    assert "unknown task 'fly'" in json.loads(unknown.task_result)['error']
    assert (bad_data.error_code, bad_data.source) == ('task_data_parsing_failed', 'Mission')
    assert json.loads(bad_data.task_result) == {
        'error': "field 'order': expected int32, got 'x' (str)"
    }
    # Results in the order the subtasks came to their turn (the topic keeps its order: once
    # the last one is here, so are the others; the mission's own result, an action's answer,
    # may come to the test before it)
    tm.wait_result_message('d')
    order = [m.task_id for m in tm.results.snapshot() if m.task_id in 'abcd']
    assert order == ['a', 'b', 'c', 'd']


def _start_held_mission(tm: Any, nav: Any, mission_id: str) -> Any:
    subtasks = [
        _subtask('navigate', HOLD, f'{mission_id}-a'),
        _subtask('navigate', 1, f'{mission_id}-b'),
    ]
    handle = tm.send('system/mission', {'subtasks': subtasks}, task_id=mission_id)
    tm.wait_in_progress(f'{mission_id}-a')
    return handle


def test_mission_cancelled_by_its_client_cancels_the_running_subtask(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, nav, _ = _launch(ros, launch_task_manager, topic_prefix)
    handle = _start_held_mission(tm, nav, 'm')

    tm.cancel(handle)

    response = tm.result_of(handle)
    assert response.status == GoalStatus.STATUS_CANCELED
    assert response.result.task_status == 'CANCELED'
    assert _rows(response.result) == [('m-a', 'CANCELED', False), ('m-b', 'RECEIVED', False)]
    assert nav.wait_for_goals(1, TIMEOUT_SEC)[0].cancel_requested.is_set()


def test_mission_cancelled_by_cancel_task_and_by_stop(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, nav, _ = _launch(ros, launch_task_manager, topic_prefix)
    first = _start_held_mission(tm, nav, 'm1')

    cancel = tm.run('system/cancel_task', {'cancelled_tasks': ['m1']})

    assert cancel.task_status == 'DONE'
    assert json.loads(cancel.task_result) == {'success': True, 'successful_cancels': ['m1']}
    first_response = tm.result_of(first)
    assert first_response.status == GoalStatus.STATUS_ABORTED  # cancelled by someone else
    assert _rows(first_response.result)[0] == ('m1-a', 'CANCELED', False)
    assert first_response.result.task_status == 'CANCELED'

    second = _start_held_mission(tm, nav, 'm2')
    stop = tm.run('system/stop', {})

    assert (stop.task_status, json.loads(stop.task_result)) == ('DONE', {'success': True})
    assert tm.result_of(second).result.task_status == 'CANCELED'


def test_new_blocking_task_pre_empting_a_blocking_subtask_ends_the_mission(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, _nav, _ = _launch(ros, launch_task_manager, topic_prefix)
    subtasks = [_subtask('navigate', HOLD, 'a', allow_skipping=True), _subtask('navigate', 1, 'b')]
    mission = tm.send('system/mission', {'subtasks': subtasks}, task_id='m')
    tm.wait_in_progress('a')

    spin = tm.run('spin', {'order': 1})

    assert spin.task_status == 'DONE'
    result = tm.result_of(mission).result
    assert result.task_status == 'ERROR'
    assert _rows(result) == [('a', 'CANCELED', False), ('b', 'RECEIVED', False)]


def test_a_new_mission_replaces_the_running_one(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, nav, _ = _launch(ros, launch_task_manager, topic_prefix)
    old = _start_held_mission(tm, nav, 'old')

    new = tm.run('system/mission', {'subtasks': [_subtask('take_photo', 1, 'p')]})

    assert new.task_status == 'DONE'
    assert tm.result_of(old).result.task_status == 'CANCELED'
