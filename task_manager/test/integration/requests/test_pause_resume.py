"""system/pause and system/resume over real DDS: restart-pausable actions, missions between
subtasks, refusals, and the ways a paused task still ends."""

import json
from typing import Any

from action_msgs.msg import GoalStatus
from rclpy.client import Client
from task_manager_msgs.msg import TaskEvent, TaskState
from task_manager_msgs.srv import GetTaskStates
from test_msgs.action import Fibonacci

from task_manager.rclpy_tools.server_wait import wait_until_ready
from task_manager.testing.harness import RosHarness, wait_for_future
from task_manager.testing.probe import TaskManagerProbe
from task_manager.testing.process import LaunchTaskManager, action_task
from task_manager.testing.servers import ScriptedActionServer

TIMEOUT_SEC = 15.0


def _launch(
    ros: RosHarness, launch: LaunchTaskManager, prefix: str
) -> tuple[TaskManagerProbe, ScriptedActionServer, ScriptedActionServer]:
    """`navigate` (pause: restart, blocking, cancelled by stop) and `photo` (not pausable)."""
    nav = ScriptedActionServer(ros.node, Fibonacci, f'{prefix}/nav')
    photo = ScriptedActionServer(ros.node, Fibonacci, f'{prefix}/photo')
    tm = launch(
        {
            'nav': action_task(
                'navigate', f'{prefix}/nav', pause='restart', blocking=True, cancel_on_stop=True
            ),
            'photo': action_task('photo', f'{prefix}/photo'),
            'dock': action_task('dock', f'{prefix}/photo', blocking=True),
        }
    )
    return tm, nav, photo


def _pause(tm: TaskManagerProbe, *task_ids: str, source: str = 'operator') -> Any:
    return tm.run('system/pause', {'task_ids': list(task_ids)}, source=source)


def _resume(tm: TaskManagerProbe, *task_ids: str, source: str = 'operator') -> Any:
    return tm.run('system/resume', {'task_ids': list(task_ids)}, source=source)


def _states(ros: RosHarness, *task_ids: str) -> list[TaskState]:
    client: Client[GetTaskStates.Request, GetTaskStates.Response] = ros.node.create_client(
        GetTaskStates, '/task_manager/get_task_states'
    )
    try:
        assert wait_until_ready(client.service_is_ready, TIMEOUT_SEC)
        request = GetTaskStates.Request(task_ids=list(task_ids))
        return list(wait_for_future(client.call_async(request), TIMEOUT_SEC, 'states').tasks)
    finally:
        ros.node.destroy_client(client)


def test_a_restart_task_pauses_by_cancelling_its_goal_and_resumes_with_the_same_goal(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, nav, _ = _launch(ros, launch_task_manager, topic_prefix)
    events = tm.record_events()
    handle = tm.send('navigate', {'order': 7}, task_id='drive', source='CLOUD')
    result = handle.get_result_async()
    first = nav.wait_for_goals(1, TIMEOUT_SEC)[0]
    tm.wait_in_progress('drive')

    paused = _pause(tm, 'drive', source='Voice control')
    tm.wait_active(lambda tasks: ('drive', 'PAUSED') in tasks, 'drive PAUSED')
    while_paused = _states(ros, 'drive')[0]
    open_while_paused = not result.done()
    resumed = _resume(tm, 'drive', source='UI')
    second = nav.wait_for_goals(2, TIMEOUT_SEC)[1]
    tm.wait_in_progress('drive')
    second.succeed(Fibonacci.Result(sequence=[7]))
    end = tm.result_of(handle)

    assert (paused.task_status, json.loads(paused.task_result)) == (
        'DONE',
        {'success': True, 'successful_pauses': ['drive'], 'errors': []},
    )
    assert first.cancel_requested.is_set() and first.ended.is_set()
    assert while_paused.task_status == 'PAUSED' and open_while_paused  # its goal stays open
    assert resumed.task_status == 'DONE'
    assert second.request.order == 7  # the same goal, sent again
    assert (end.result.task_status, end.status) == ('DONE', GoalStatus.STATUS_SUCCEEDED)
    assert json.loads(end.result.task_result) == {'sequence': [7]}
    kinds = [
        e.event
        for e in events.wait_until(
            lambda msgs: (
                [m for m in msgs if m.task.task_id == 'drive'] or None
                if any(m.task.task_id == 'drive' and m.event == TaskEvent.ENDED for m in msgs)
                else None
            ),
            TIMEOUT_SEC,
            'the events of drive',
        )
    ]
    assert kinds == ['RECEIVED', 'STARTED', 'PAUSED', 'RESUMED', 'ENDED']
    stored = _states(ros, 'drive')[0]
    pauses = json.loads(stored.pauses)
    assert [(p['paused_by'], p['resumed_by']) for p in pauses] == [('Voice control', 'UI')]
    assert pauses[0]['resumed'] > pauses[0]['paused'] > 0
    assert stored.paused_sec == pauses[0]['resumed'] - pauses[0]['paused']


def test_a_task_that_cannot_pause_and_a_resume_of_a_running_task_are_clear_errors(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, nav, photo = _launch(ros, launch_task_manager, topic_prefix)
    tm.send('photo', {'order': 1}, task_id='snap')
    tm.send('navigate', {'order': 2}, task_id='drive')
    photo.wait_for_goals(1, TIMEOUT_SEC)
    nav.wait_for_goals(1, TIMEOUT_SEC)
    tm.wait_active(lambda tasks: {('snap', 'IN_PROGRESS'), ('drive', 'IN_PROGRESS')} <= set(tasks))

    refused = _pause(tm, 'snap', 'drive', 'nobody')
    not_paused = _resume(tm, 'snap')

    assert refused.task_status == 'ERROR'
    result = json.loads(refused.task_result)
    assert (result['success'], result['successful_pauses']) == (False, ['drive'])
    assert result['errors'] == [
        'task snap (photo) cannot be paused: its entry declares pause: none (the default); '
        'pause: restart pauses an action task by cancelling its goal and sending it again '
        'on resume',
        "no active task 'nobody' to pause",
    ]
    assert not_paused.task_status == 'ERROR'
    assert json.loads(not_paused.task_result)['errors'] == [
        'task snap (photo) is not paused (it is IN_PROGRESS); only a paused task can be resumed'
    ]
    assert [s.task_status for s in _states(ros, 'snap', 'drive')] == ['IN_PROGRESS', 'PAUSED']


def test_a_paused_task_ends_canceled_by_stop_and_by_a_conflicting_blocking_task(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, nav, photo = _launch(ros, launch_task_manager, topic_prefix)
    stopped = tm.send('navigate', {'order': 1}, task_id='stopped')
    nav.wait_for_goals(1, TIMEOUT_SEC)
    tm.wait_in_progress('stopped')
    _pause(tm, 'stopped')
    stop = tm.run('system/stop', {})
    stopped_end = tm.result_of(stopped)
    preempted = tm.send('navigate', {'order': 2}, task_id='preempted')
    nav.wait_for_goals(2, TIMEOUT_SEC)
    tm.wait_in_progress('preempted')
    _pause(tm, 'preempted')
    dock = tm.send('dock', {'order': 3}, task_id='dock')
    preempted_end = tm.result_of(preempted)
    photo.wait_for_goals(1, TIMEOUT_SEC)[0].succeed(Fibonacci.Result())
    tm.result_of(dock)

    assert stop.task_status == 'DONE'
    assert (stopped_end.result.task_status, stopped_end.status) == (
        'CANCELED',
        GoalStatus.STATUS_ABORTED,
    )
    assert preempted_end.result.task_status == 'CANCELED'
    assert len(nav.goals.items) == 2  # a paused task's goal is not sent again to be cancelled
    assert [m.task_status for m in tm.results_for('stopped')] == ['CANCELED']


def _subtask(name: str, order: int, task_id: str) -> dict[str, Any]:
    return {'task_id': task_id, 'task_name': name, 'task_data': json.dumps({'order': order})}


def test_a_mission_pauses_between_subtasks_and_resumes_with_the_next(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, _, photo = _launch(ros, launch_task_manager, topic_prefix)
    mission = tm.send(
        'system/mission',
        {'subtasks': [_subtask('photo', 1, 'first'), _subtask('photo', 2, 'second')]},
        task_id='tour',
    )
    first = photo.wait_for_goals(1, TIMEOUT_SEC)[0]
    tm.wait_in_progress('first')

    _pause(tm, 'tour', source='operator')
    tm.wait_active(lambda tasks: ('tour', 'PAUSED') in tasks, 'tour PAUSED')
    first.succeed(Fibonacci.Result(sequence=[1]))
    assert tm.wait_result_message('first').task_status == 'DONE'
    held = _states(ros)
    resumed = _resume(tm, 'tour')
    photo.wait_for_goals(2, TIMEOUT_SEC)[1].succeed(Fibonacci.Result(sequence=[2]))
    end = tm.result_of(mission)

    assert [(s.task_id, s.task_status) for s in held] == [('tour', 'PAUSED')]
    assert resumed.task_status == 'DONE'
    assert end.result.task_status == 'DONE'
    rows = json.loads(end.result.task_result)['mission_results']
    assert [(r['task_id'], r['task_status']) for r in rows] == [
        ('first', 'DONE'),
        ('second', 'DONE'),
    ]
    ended = _history(ros, 'tour')
    assert ended.paused_sec > 0 and json.loads(ended.pauses)[0]['paused_by'] == 'operator'


def test_pausing_a_mission_pauses_its_restartable_subtask_at_once(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, nav, _ = _launch(ros, launch_task_manager, topic_prefix)
    mission = tm.send(
        'system/mission', {'subtasks': [_subtask('navigate', 5, 'leg')]}, task_id='patrol'
    )
    first = nav.wait_for_goals(1, TIMEOUT_SEC)[0]
    tm.wait_in_progress('leg')

    _pause(tm, 'patrol')
    tm.wait_active(lambda tasks: {('patrol', 'PAUSED'), ('leg', 'PAUSED')} <= set(tasks))
    _resume(tm, 'patrol')
    second = nav.wait_for_goals(2, TIMEOUT_SEC)[1]
    second.succeed(Fibonacci.Result(sequence=[5]))
    end = tm.result_of(mission)

    assert first.cancel_requested.is_set()
    assert second.request.order == 5
    assert end.result.task_status == 'DONE'
    assert json.loads(_history(ros, 'leg').pauses)[0]['paused_by'] == 'operator'


def _history(ros: RosHarness, task_id: str) -> TaskState:
    """The stored end of `task_id` (an ended task's state comes from the history)."""
    (state,) = _states(ros, task_id)
    assert state.sequence > 0, f'{task_id} has not ended'
    return state
