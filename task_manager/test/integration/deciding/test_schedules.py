"""system/schedule, unschedule and enable_schedule over real DDS, with short real periods:
runs are ordinary tasks, overlap policies, restarts and the misfire rule, refusals.

When each kind of schedule fires (cron and time zones included) is tested against a clock
the tests control in test/unit/schedules/.
"""

import json
import sqlite3
import time
from pathlib import Path
from typing import Any

from rclpy.client import Client
from task_manager_msgs.msg import Schedule
from task_manager_msgs.srv import GetSchedules, GetTaskStates
from test_msgs.action import Fibonacci

from task_manager.rclpy_tools.server_wait import wait_until_ready
from task_manager.testing.harness import RosHarness, WaitTimeoutError, wait_for_future
from task_manager.testing.probe import TaskManagerProbe
from task_manager.testing.process import LaunchTaskManager, action_task
from task_manager.testing.servers import ScriptedActionServer, ScriptedGoal

TIMEOUT_SEC = 15.0
PERIOD_SEC = 0.3
HOLD = 50  # Fibonacci orders at or above it are held by the server until the test ends them


def _decide(goal: ScriptedGoal) -> None:
    if goal.request.order < HOLD:
        goal.succeed(Fibonacci.Result(sequence=[goal.request.order]))


def _launch(
    ros: RosHarness, launch: LaunchTaskManager, prefix: str, **parameters: Any
) -> tuple[TaskManagerProbe, ScriptedActionServer]:
    """`work` (not reentrant) and `parallel` (reentrant), on one scripted server."""
    server = ScriptedActionServer(ros.node, Fibonacci, f'{prefix}/fib', on_goal=_decide)
    tm = launch(
        {
            'work': action_task('work', f'{prefix}/fib'),
            'parallel': action_task('parallel', f'{prefix}/fib', reentrant=True),
        },
        **parameters,
    )
    return tm, server


def _schedule(
    tm: TaskManagerProbe, schedule_id: str, task_name: str, order: int, **when: Any
) -> Any:
    request = {
        'schedule_id': schedule_id,
        'task_name': task_name,
        'task_data': json.dumps({'order': order}),
        **when,
    }
    return tm.run('system/schedule', request, source='CLI')


def _schedules(ros: RosHarness, *schedule_ids: str) -> dict[str, Schedule]:
    client: Client[GetSchedules.Request, GetSchedules.Response] = ros.node.create_client(
        GetSchedules, '/task_manager/get_schedules'
    )
    try:
        assert wait_until_ready(client.service_is_ready, TIMEOUT_SEC)
        request = GetSchedules.Request(schedule_ids=list(schedule_ids))
        found = wait_for_future(client.call_async(request), TIMEOUT_SEC, 'schedules').schedules
        return {s.schedule_id: s for s in found}
    finally:
        ros.node.destroy_client(client)


def _wait_schedule(ros: RosHarness, schedule_id: str, condition: Any, what: str) -> Schedule:
    """Ask for the schedule until `condition(schedule)` holds (each ask is a round trip)."""
    deadline = time.monotonic() + TIMEOUT_SEC
    while time.monotonic() < deadline:
        schedule = _schedules(ros, schedule_id)[schedule_id]
        if condition(schedule):
            return schedule
    raise WaitTimeoutError(f'schedule {schedule_id}: {what} within {TIMEOUT_SEC} s')


def _states(ros: RosHarness, task_id: str) -> Any:
    """The task's state, from the node (the history once it has ended)."""
    client: Client[GetTaskStates.Request, GetTaskStates.Response] = ros.node.create_client(
        GetTaskStates, '/task_manager/get_task_states'
    )
    try:
        assert wait_until_ready(client.service_is_ready, TIMEOUT_SEC)
        request = GetTaskStates.Request(task_ids=[task_id])
        return wait_for_future(client.call_async(request), TIMEOUT_SEC, 'states').tasks[0]
    finally:
        ros.node.destroy_client(client)


def _started(ros: RosHarness, task_id: str) -> tuple[float, float]:
    """(started, ended) of an ended task, from the history."""
    task = _states(ros, task_id)
    return (
        task.started.sec + task.started.nanosec * 1e-9,
        task.ended.sec + task.ended.nanosec * 1e-9,
    )


def _seconds(stamp: Any) -> float:
    return float(stamp.sec + stamp.nanosec * 1e-9)


def test_one_shot_and_periodic_schedules_start_ordinary_runs(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, server = _launch(ros, launch_task_manager, topic_prefix)

    once = _schedule(tm, 'once', 'work', 1, delay_sec=0.2)
    asked = time.time()  # before `every` exists: its period times come after this
    every = _schedule(tm, 'every', 'parallel', 2, period_sec=PERIOD_SEC, max_runs=3)
    runs = [tm.wait_result_message(t) for t in ('once-run-1', 'every-run-1', 'every-run-2')]
    runs.append(tm.wait_result_message('every-run-3'))
    schedules = _schedules(ros)

    assert (once.task_status, every.task_status) == ('DONE', 'DONE')
    assert json.loads(once.task_result)['schedule_id'] == 'once'
    assert [(r.task_name, r.task_status, r.source) for r in runs] == [
        ('work', 'DONE', 'schedule:once'),
        ('parallel', 'DONE', 'schedule:every'),
        ('parallel', 'DONE', 'schedule:every'),
        ('parallel', 'DONE', 'schedule:every'),
    ]
    assert sorted(g.request.order for g in server.goals.items) == [1, 2, 2, 2]
    starts = [_started(ros, f'every-run-{run}')[0] for run in (1, 2, 3)]
    # never early: the k-th run at k periods after the schedule's creation or later (a loaded
    # machine may start the first late, and so the second less than a period after it)
    assert all(start >= asked + run * PERIOD_SEC for run, start in enumerate(starts, 1)), starts
    done = schedules['once']
    assert (done.run_count, done.last_task_id, done.last_status) == (1, 'once-run-1', 'DONE')
    assert (done.created_by, _seconds(done.next_run), done.enabled) == ('CLI', 0.0, True)
    assert done.description.startswith('once at ')
    periodic = schedules['every']
    assert (periodic.run_count, periodic.missed_count, periodic.skipped_count) == (3, 0, 0)
    assert periodic.description == 'every 0.3 s, at most 3 runs'
    assert _seconds(periodic.next_run) == 0.0  # max_runs reached


def test_overlap_skip_buffer_one_and_cancel_other(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, server = _launch(ros, launch_task_manager, topic_prefix)

    _schedule(tm, 'skip', 'work', HOLD, period_sec=0.2)
    held = server.wait_for_goals(1, TIMEOUT_SEC)[0]
    skipping = _wait_schedule(ros, 'skip', lambda s: s.skipped_count >= 2, 'two runs skipped')
    tm.run('system/unschedule', {'schedule_ids': ['skip']})
    held.succeed(Fibonacci.Result())
    skip_end = tm.wait_result_message('skip-run-1')

    _schedule(tm, 'buffer', 'parallel', HOLD + 1, period_sec=0.2, overlap='buffer_one')
    first = server.wait_for_goals(2, TIMEOUT_SEC)[1]
    _wait_schedule(ros, 'buffer', lambda s: s.skipped_count >= 1, 'one buffered, then skips')
    first.succeed(Fibonacci.Result())
    buffered = server.wait_for_goals(3, TIMEOUT_SEC)[2]
    tm.run('system/unschedule', {'schedule_ids': ['buffer']})
    buffered.succeed(Fibonacci.Result())
    tm.wait_result_message('buffer-run-2')

    _schedule(tm, 'replace', 'parallel', HOLD + 2, period_sec=0.3, overlap='CANCEL_OTHER')
    server.wait_for_goals(5, TIMEOUT_SEC)
    tm.run('system/unschedule', {'schedule_ids': ['replace']})
    replaced = tm.wait_result_message('replace-run-1')

    assert skipping.run_count == 1 and skip_end.task_status == 'DONE'
    assert [g.request.order for g in server.goals.items[:3]] == [HOLD, HOLD + 1, HOLD + 1]
    ended_first = _started(ros, 'buffer-run-1')[1]
    assert _started(ros, 'buffer-run-2')[0] >= ended_first  # right after, not alongside
    assert replaced.task_status == 'CANCELED'
    for goal in server.goals.items[4:]:
        goal.succeed(Fibonacci.Result())


def test_allow_all_runs_overlap_and_is_refused_for_a_task_that_is_not_reentrant(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, server = _launch(ros, launch_task_manager, topic_prefix)

    refused = _schedule(tm, 'bad', 'work', 1, period_sec=1.0, overlap='ALLOW_ALL')
    _schedule(tm, 'all', 'parallel', HOLD, period_sec=0.2, overlap='ALLOW_ALL')
    both = server.wait_for_goals(2, TIMEOUT_SEC)
    tm.run('system/unschedule', {'schedule_ids': ['all']})
    tm.wait_active(
        lambda tasks: {('all-run-1', 'IN_PROGRESS'), ('all-run-2', 'IN_PROGRESS')} <= set(tasks)
    )
    for goal in server.goals.items:
        goal.succeed(Fibonacci.Result())

    assert (refused.task_status, refused.error_code) == ('ERROR', 'task_data_parsing_failed')
    assert 'ALLOW_ALL runs overlap, and work is not reentrant' in refused.task_result
    assert len(both) == 2


def test_bad_schedules_are_refused_with_the_field_and_what_is_allowed(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, _ = _launch(ros, launch_task_manager, topic_prefix)

    two_whens = _schedule(tm, 'x', 'work', 1, at='2030-01-01T02:00:00+01:00', cron='0 2 * * *')
    naive = _schedule(tm, 'x', 'work', 1, at='2030-01-01T02:00:00')
    bad_cron = _schedule(tm, 'x', 'work', 1, cron='61 * * * *')
    unknown = _schedule(tm, 'x', 'no/such', 1, period_sec=10.0)
    bad_data = tm.run(
        'system/schedule',
        {'task_name': 'work', 'task_data': '{"order": "many"}', 'period_sec': 10.0},
    )
    kept = _schedule(tm, 'twice', 'work', 1, period_sec=60.0)
    again = _schedule(tm, 'twice', 'work', 1, period_sec=60.0)
    missing = tm.run('system/unschedule', {'schedule_ids': ['twice', 'nothing']})
    ghost = {'task_id': 'ghost', 'task_name': 'no/such', 'task_data': '{}'}
    bad_mission = tm.run(
        'system/schedule',
        {
            'task_name': 'system/mission',
            'task_data': json.dumps({'subtasks': [ghost]}),
            'period_sec': 10.0,
        },
        task_id='bad-mission',
    )
    # results come in order: a refusal of the subtask would be before the schedule's own
    tm.wait_result_message('bad-mission')

    for refused in (two_whens, naive, bad_cron, unknown, bad_data, again):
        assert (refused.task_status, refused.error_code) == ('ERROR', 'task_data_parsing_failed')
    assert 'give exactly one of at, delay_sec, period_sec, cron' in two_whens.task_result
    assert 'zone' in naive.task_result
    assert "e.g. '0 2 * * *'" in json.loads(bad_cron.task_result)['error']
    assert 'declared tasks: parallel, system/' in unknown.task_result
    assert 'not a valid goal of work' in bad_data.task_result
    assert kept.task_status == 'DONE' and "schedule 'twice' exists" in again.task_result
    assert missing.task_status == 'ERROR'
    assert json.loads(missing.task_result) == {
        'success': False,
        'removed': ['twice'],
        'errors': ["no schedule 'nothing'"],
    }
    assert bad_mission.error_code == 'task_data_parsing_failed'
    assert 'subtasks[0].task_name' in bad_mission.task_result
    assert tm.results_for('ghost') == []  # scheduling a mission starts none of its subtasks
    assert _schedules(ros) == {}


def test_a_disabled_schedule_keeps_its_state_and_runs_again_once_enabled(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, _ = _launch(ros, launch_task_manager, topic_prefix)
    _schedule(tm, 'tick', 'parallel', 1, period_sec=0.2)
    tm.wait_result_message('tick-run-1')

    disabled = tm.run('system/enable_schedule', {'schedule_ids': ['tick'], 'enabled': False})
    off = _schedules(ros, 'tick')['tick']
    enabled = tm.run('system/enable_schedule', {'schedule_ids': ['tick'], 'enabled': True})
    later = tm.wait_result_message(f'tick-run-{off.run_count + 1}')
    tm.run('system/unschedule', {'schedule_ids': ['tick']})

    assert (disabled.task_status, enabled.task_status) == ('DONE', 'DONE')
    assert not off.enabled and _seconds(off.next_run) == 0.0 and off.run_count >= 1
    assert later.task_status == 'DONE'


def test_a_restart_keeps_schedules_and_runs_a_missed_run_once_within_its_grace(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str, tmp_path: Path
) -> None:
    history = tmp_path / 'kept.sqlite'
    first, _ = _launch(ros, launch_task_manager, topic_prefix, history_path=str(history))
    created = time.time()
    _schedule(first, 'catch-up', 'work', 1, delay_sec=1.0)
    _schedule(first, 'too-late', 'parallel', 2, delay_sec=1.0, misfire_grace_sec=0.2)
    _schedule(first, 'tick', 'parallel', 3, period_sec=0.2)
    first.wait_result_message('tick-run-1')
    first.process.stop()  # type: ignore[attr-defined]
    # The Task Manager stays down past the due times: the scenario, not a synchronisation.
    time.sleep(max(0.0, created + 1.6 - time.time()))

    # The missed run starts as the node starts, while DDS may still be discovering this
    # process's server: the node waits up to server_wait_timeout for it (1 s by default).
    second, _ = _launch(
        ros, launch_task_manager, topic_prefix, history_path=str(history), server_wait_timeout=10.0
    )
    # The catch-up run may end before this test's subscriber of the (volatile) results topic
    # matched the new node: its end is read from the schedule and the history instead.
    _wait_schedule(
        ros, 'catch-up', lambda s: s.last_status in ('DONE', 'ERROR', 'CANCELED'), 'run ended'
    )
    caught_up = _states(ros, 'catch-up-run-1')
    tick = _wait_schedule(ros, 'tick', lambda s: s.missed_count > 0, 'missed runs counted')
    second.run('system/unschedule', {'schedule_ids': ['tick']})
    schedules = _schedules(ros)

    assert caught_up.task_status == 'DONE'
    assert [m.task_status for m in second.results_for('catch-up-run-1')] in ([], ['DONE'])
    # at least 1 s down at 0.2 s: the due runs are coalesced into one, the others missed
    assert tick.missed_count >= 3 and tick.run_count >= 2
    assert (schedules['catch-up'].run_count, schedules['catch-up'].missed_count) == (1, 0)
    too_late = schedules['too-late']
    assert (too_late.run_count, too_late.missed_count, _seconds(too_late.next_run)) == (0, 1, 0)
    assert second.results_for('too-late-run-1') == []
    assert set(schedules) == {'catch-up', 'too-late'}


def test_a_stored_schedule_outside_the_bounds_is_reported_and_set_aside_at_start(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str, tmp_path: Path
) -> None:
    """An older version stored `period_sec: 1e300`; every read of the schedules then crashed
    the node, restarts included."""
    history = tmp_path / 'old.sqlite'
    first, _ = _launch(ros, launch_task_manager, topic_prefix, history_path=str(history))
    _schedule(first, 'kept', 'work', 1, period_sec=3600)
    _schedule(first, 'broken', 'work', 1, period_sec=3600)
    first.process.stop()  # type: ignore[attr-defined]
    with sqlite3.connect(history) as db:
        (text,) = db.execute("SELECT spec FROM schedules WHERE schedule_id = 'broken'").fetchone()
        db.execute(
            "UPDATE schedules SET spec = ? WHERE schedule_id = 'broken'",
            (json.dumps({**json.loads(text), 'period_sec': 1e300}),),
        )

    second, _ = _launch(ros, launch_task_manager, topic_prefix, history_path=str(history))

    line = second.process.wait_for_log(r"schedule 'broken' .*", TIMEOUT_SEC)  # type: ignore[attr-defined]
    assert 'period_sec must be from 0.1 to 31622400 s, got 1e+300' in line
    assert set(_schedules(ros)) == {'kept'}
    assert second.run('parallel', {'order': 1}).task_status == 'DONE'
