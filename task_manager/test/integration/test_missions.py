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
    seen_active = {t.task_id for m in tm.active.snapshot() for t in m.active_tasks}
    assert {'m1', 'n1', 'n2', rows[1][0]} <= seen_active


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


def test_mission_with_an_unknown_or_malformed_subtask_is_rejected_before_it_starts(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, nav, _ = _launch(ros, launch_task_manager, topic_prefix)

    unknown = tm.run('system/mission', {'subtasks': [_subtask('navigate', 1), _subtask('fly', 1)]})
    malformed = tm.run(
        'system/mission',
        {
            'subtasks': [
                _subtask('navigate', 1),
                {'task_name': 'navigate', 'task_data': '{"order": "x"}'},
            ]
        },
    )

    for result in (unknown, malformed):
        assert (result.task_status, result.error_code) == ('ERROR', 'task_data_parsing_failed')
    assert nav.goals.items == []


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
