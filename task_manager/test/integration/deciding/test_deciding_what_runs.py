"""Deciding what runs (issue 29): resources, priorities, the queue, timeouts and retries,
each decision explained, on a node started from a parameters file with real servers."""

import json
import time
from typing import Any

from action_msgs.msg import GoalStatus
from task_manager_msgs.msg import TaskEvent
from test_msgs.action import Fibonacci

from task_manager.client import TaskManagerClient
from task_manager.core.names import TASK_EVENTS_TOPIC
from task_manager.rclpy_tools import qos
from task_manager.testing.harness import RosHarness, TopicRecorder
from task_manager.testing.probe import TaskManagerProbe
from task_manager.testing.process import LaunchTaskManager, action_task
from task_manager.testing.servers import ScriptedActionServer

TIMEOUT_SEC = 15.0


def robot(
    ros: RosHarness, launch: LaunchTaskManager, prefix: str, **entries: dict[str, Any]
) -> tuple[TaskManagerProbe, dict[str, ScriptedActionServer]]:
    """A node with a drive and a dock on `base` and a photo on `camera` (and `entries`)."""
    tasks = {
        'drive': action_task('drive', f'{prefix}/drive', resources=['base']),
        'dock': action_task('dock', f'{prefix}/dock', resources=['base']),
        'photo': action_task('photo', f'{prefix}/photo', resources=['camera']),
        **entries,
    }
    servers = {
        key: ScriptedActionServer(ros.node, Fibonacci, entry['topic'])
        for key, entry in tasks.items()
    }
    return launch(tasks), servers


def events_of(ros: RosHarness) -> TopicRecorder:
    return ros.record(TaskEvent, TASK_EVENTS_TOPIC, qos.TASK_EVENTS)


def wait_event(events: TopicRecorder, task_id: str, kind: str) -> TaskEvent:
    return events.wait_until(
        lambda msgs: next((m for m in msgs if m.task.task_id == task_id and m.event == kind), None),
        TIMEOUT_SEC,
        f'{kind} of {task_id}',
    )


def test_tasks_on_different_resources_run_side_by_side_and_one_on_the_same_preempts(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, servers = robot(ros, launch_task_manager, topic_prefix)
    events = events_of(ros)
    drive = tm.send('drive', {'order': 1}, task_id='drive-1')
    photo = tm.send('photo', {'order': 1}, task_id='photo-1')
    tm.wait_active(lambda t: {('drive-1', 'IN_PROGRESS'), ('photo-1', 'IN_PROGRESS')} <= set(t))

    tm.send('dock', {'order': 1}, task_id='dock-1')

    ended = tm.result_of(drive).result
    assert ended.task_status == 'CANCELED'
    # the server's result as it sent it, nothing added: why is in the event and decisions
    assert json.loads(ended.task_result) == {'sequence': []}
    ended_event = wait_event(events, 'drive-1', 'ENDED')
    assert ended_event.reason == 'cancelled: pre-empted by dock-1 (priority 0) for base'
    assert json.loads(ended_event.task.decisions)[-1]['reason'] == ended_event.reason
    tm.wait_in_progress('dock-1')
    assert not servers['photo'].wait_for_goals(1, TIMEOUT_SEC)[0].cancel_requested.is_set()
    servers['photo'].wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    assert tm.result_of(photo).result.task_status == 'DONE'


def test_a_queued_task_waits_listed_queued_and_starts_when_the_resource_is_freed(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, servers = robot(ros, launch_task_manager, topic_prefix)
    events = events_of(ros)
    tm.start('drive', {'order': 1}, task_id='drive-1', priority=5)
    tm.wait_in_progress('drive-1')

    dock = tm.start('dock', {'order': 1}, task_id='dock-1', on_conflict='queue')

    tm.wait_active(lambda t: ('dock-1', 'QUEUED') in t and ('drive-1', 'IN_PROGRESS') in t)
    queued = wait_event(events, 'dock-1', 'QUEUED')
    assert queued.reason == 'queued behind drive-1 (priority 5), which holds base'
    assert queued.task.queue_position == 1
    assert servers['dock'].goals.items == []
    servers['drive'].wait_for_goals(1, TIMEOUT_SEC)[0].succeed()

    tm.wait_in_progress('dock-1')
    started = wait_event(events, 'dock-1', 'STARTED')
    assert started.reason.startswith('its turn came after')
    servers['dock'].wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    assert tm.result_of(dock).result.task_status == 'DONE'
    decisions = json.loads(wait_event(events, 'dock-1', 'ENDED').task.decisions)
    assert [d['decision'] for d in decisions] == ['queued', 'started']


def test_a_lower_priority_is_refused_and_the_running_task_goes_on(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, servers = robot(ros, launch_task_manager, topic_prefix)
    drive = tm.start('drive', {'order': 1}, task_id='drive-12', priority=5)
    tm.wait_in_progress('drive-12')

    refused = tm.result_of(tm.start('dock', {'order': 1}, task_id='dock-3', priority=1))

    assert refused.status == GoalStatus.STATUS_ABORTED
    assert (refused.result.task_status, refused.result.error_code) == (
        'ERROR',
        'preemption_refused',
    )
    assert json.loads(refused.result.task_result)['error'] == (
        "refused: priority 1 is below drive-12's 5, which holds base"
    )
    goal = servers['drive'].wait_for_goals(1, TIMEOUT_SEC)[0]
    assert not goal.cancel_requested.is_set()
    goal.succeed()
    assert tm.result_of(drive).result.task_status == 'DONE'


def test_reject_and_a_full_queue_are_refused_with_their_codes(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, servers = robot(ros, launch_task_manager, topic_prefix)
    tm.send('drive', {'order': 1}, task_id='drive-1')
    tm.wait_in_progress('drive-1')

    busy = tm.run_started('dock', {'order': 1}, task_id='dock-1', on_conflict='reject')

    assert (busy.task_status, busy.error_code) == ('ERROR', 'resource_busy')
    assert json.loads(busy.task_result)['error'] == (
        'refused: drive-1 (priority 0), which holds base'
    )
    servers['drive'].wait_for_goals(1, TIMEOUT_SEC)[0].succeed()


def test_a_timeout_cancels_the_task_on_its_server_and_ends_it_error_timeout(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, servers = robot(ros, launch_task_manager, topic_prefix)
    events = events_of(ros)
    began = time.monotonic()

    ended = tm.run_started('drive', {'order': 1}, task_id='drive-1', timeout_sec=1.0)

    took_sec = time.monotonic() - began
    assert (ended.task_status, ended.error_code) == ('ERROR', 'timeout')
    assert json.loads(ended.task_result) == {'sequence': []}  # the server's, nothing added
    ended_event = wait_event(events, 'drive-1', 'ENDED')
    assert ended_event.reason == 'timed out: ran 1 s (timeout_sec)'
    assert servers['drive'].wait_for_goals(1, TIMEOUT_SEC)[0].cancel_requested.is_set()
    assert took_sec < 3.0


def test_a_queue_timeout_ends_the_task_before_it_starts(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, servers = robot(ros, launch_task_manager, topic_prefix)
    tm.send('drive', {'order': 1}, task_id='drive-1')
    tm.wait_in_progress('drive-1')

    ended = tm.run_started(
        'dock', {'order': 1}, task_id='dock-1', on_conflict='queue', queue_timeout_sec=0.5
    )

    assert (ended.task_status, ended.error_code) == ('ERROR', 'timeout')
    assert 'in the queue' in json.loads(ended.task_result)['error']
    assert servers['dock'].goals.items == []
    servers['drive'].wait_for_goals(1, TIMEOUT_SEC)[0].succeed()


def test_an_action_without_feedback_for_too_long_is_stalled(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, servers = robot(ros, launch_task_manager, topic_prefix)
    events = events_of(ros)

    ended = tm.run_started('photo', {'order': 1}, task_id='photo-1', feedback_timeout_sec=0.5)

    assert (ended.task_status, ended.error_code) == ('ERROR', 'timeout')
    assert json.loads(ended.task_result) == {'sequence': []}
    assert 'stalled' in wait_event(events, 'photo-1', 'ENDED').reason
    assert servers['photo'].wait_for_goals(1, TIMEOUT_SEC)[0].cancel_requested.is_set()


def test_a_declared_retry_runs_the_task_again_until_it_succeeds(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    retry = {'max_attempts': 3, 'initial_delay_sec': 0.1, 'multiplier': 2.0}
    flaky = action_task('flaky', f'{topic_prefix}/flaky', retry=retry)
    tm, servers = robot(ros, launch_task_manager, topic_prefix, flaky=flaky)
    events = events_of(ros)

    handle = tm.send('flaky', {'order': 1}, task_id='flaky-1')
    servers['flaky'].wait_for_goals(1, TIMEOUT_SEC)[0].abort()
    servers['flaky'].wait_for_goals(2, TIMEOUT_SEC)[1].abort()
    servers['flaky'].wait_for_goals(3, TIMEOUT_SEC)[2].succeed()

    assert tm.result_of(handle).result.task_status == 'DONE'
    ended = wait_event(events, 'flaky-1', 'ENDED').task
    assert ended.attempt == 3
    decisions = json.loads(ended.decisions)
    assert [d['decision'] for d in decisions] == ['retry', 'retry']
    assert decisions[0]['reason'] == (
        'retry: attempt 1 of 3 ended ERROR (its server failed it); attempt 2 in 0.1 s'
    )


def test_a_task_cancelled_while_its_retry_starts_ends_canceled_as_on_its_first_attempt(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    retry = {'max_attempts': 3, 'initial_delay_sec': 0.1}
    tm = launch_task_manager({'flaky': action_task('flaky', f'{topic_prefix}/flaky', retry=retry)})
    server = ScriptedActionServer(
        ros.node, Fibonacci, f'{topic_prefix}/flaky', hold_goal_requests=True
    )

    handle = tm.send('flaky', {'order': 1}, task_id='flaky-1')
    server.wait_for_held(1, TIMEOUT_SEC)[0].reject()
    second = server.wait_for_held(2, TIMEOUT_SEC)[1]  # the retry is starting on its server
    tm.cancel(handle)
    second.reject()

    ended = tm.result_of(handle).result
    assert (ended.task_status, ended.error_code) == ('CANCELED', '')
    assert 'rejected the goal' in json.loads(ended.task_result)['error']


def test_a_queued_task_moves_up_when_its_priority_is_raised(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, servers = robot(ros, launch_task_manager, topic_prefix)
    tm.send('drive', {'order': 1}, task_id='drive-1')
    tm.wait_in_progress('drive-1')
    tm.start('dock', {'order': 1}, task_id='first', on_conflict='queue')
    tm.start('dock', {'order': 2}, task_id='second', on_conflict='queue')
    tm.wait_active(lambda t: ('second', 'QUEUED') in t)

    changed = tm.run('system/reprioritize', {'task_ids': ['second'], 'priority': 3})

    assert changed.task_status == 'DONE', changed.task_result
    servers['drive'].wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    tm.wait_in_progress('second')
    tm.wait_active(lambda t: ('first', 'QUEUED') in t)


def test_a_queued_task_cancelled_by_its_client_never_starts(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, servers = robot(ros, launch_task_manager, topic_prefix)
    tm.send('drive', {'order': 1}, task_id='drive-1')
    tm.wait_in_progress('drive-1')
    dock = tm.start('dock', {'order': 1}, task_id='dock-1', on_conflict='queue')
    tm.wait_active(lambda t: ('dock-1', 'QUEUED') in t)

    tm.cancel(dock)

    ended = tm.result_of(dock)
    assert (ended.status, ended.result.task_status) == (GoalStatus.STATUS_CANCELED, 'CANCELED')
    servers['drive'].wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    tm.wait_result_message('drive-1')
    assert servers['dock'].goals.items == []


def test_a_schedule_runs_its_task_with_the_options_it_was_given(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, servers = robot(ros, launch_task_manager, topic_prefix)
    events = events_of(ros)
    tm.start('drive', {'order': 1}, task_id='drive-1', priority=5)
    tm.wait_in_progress('drive-1')
    schedule = {
        'schedule_id': 'dock-soon',
        'task_name': 'dock',
        'task_data': json.dumps({'order': 1}),
        'delay_sec': 0.2,
        'options': {'on_conflict': 'queue', 'priority': 2},
    }

    assert tm.run('system/schedule', schedule).task_status == 'DONE'

    queued = events.wait_until(
        lambda msgs: next(
            (m for m in msgs if m.task.task_name == 'dock' and m.event == 'QUEUED'), None
        ),
        TIMEOUT_SEC,
        'the scheduled dock queued',
    )
    assert queued.task.priority == 2
    assert queued.reason == 'queued behind drive-1 (priority 5), which holds base'
    servers['drive'].wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    servers['dock'].wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    assert wait_event(events, queued.task.task_id, 'ENDED').task.task_status == 'DONE'


def test_a_mission_queues_as_one_unit_and_its_subtasks_use_what_it_holds(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, servers = robot(ros, launch_task_manager, topic_prefix)
    tm.send('drive', {'order': 1}, task_id='drive-1')
    tm.wait_in_progress('drive-1')
    subtasks = [
        {'task_id': 'm-dock', 'task_name': 'dock', 'task_data': '{"order": 1}'},
        {'task_id': 'm-photo', 'task_name': 'photo', 'task_data': '{"order": 1}'},
    ]

    mission = tm.start('system/mission', {'subtasks': subtasks}, task_id='m', on_conflict='queue')

    tm.wait_active(lambda t: ('m', 'QUEUED') in t)
    servers['drive'].wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    dock = servers['dock'].wait_for_goals(1, TIMEOUT_SEC)[0]

    refused = tm.run_started('drive', {'order': 1}, task_id='late', on_conflict='reject')

    assert refused.error_code == 'resource_busy'
    assert json.loads(refused.task_result)['error'].startswith(
        'refused: m (priority 0), which holds base'
    )
    dock.succeed()
    servers['photo'].wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    assert tm.result_of(mission).result.task_status == 'DONE'


def test_the_places_in_the_queue_move_up_when_the_first_queued_task_starts(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, servers = robot(ros, launch_task_manager, topic_prefix)
    tm.send('drive', {'order': 1}, task_id='drive-1')
    tm.wait_in_progress('drive-1')
    for name in ('a', 'b', 'c'):
        tm.start('dock', {'order': 1}, task_id=name, on_conflict='queue')
    tm.wait_active(lambda t: ('c', 'QUEUED') in t)

    servers['drive'].wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    tm.wait_in_progress('a')

    with TaskManagerClient('test_queue_places', timeout_sec=TIMEOUT_SEC) as client:
        client.wait_until_available()
        places = {s.task_id: s.queue_position for s in client.task_states(['a', 'b', 'c'])}
    assert places == {'a': 0, 'b': 1, 'c': 2}
