"""taskctl pause/resume and taskctl schedule as a user runs them, and the Python client's
pause and resume, against a real node over DDS (the node's own semantics are in
test_pause_resume.py and test_schedules.py)."""

import json
import re
import threading
import time
from collections.abc import Callable
from datetime import datetime, timedelta
from pathlib import Path
from typing import Any

from test_msgs.action import Fibonacci

from task_manager.client import TaskEvent, TaskEventKind, TaskManagerClient
from task_manager.core.status import TaskStatus
from task_manager.testing.harness import RosHarness, WaitTimeoutError
from task_manager.testing.probe import TaskManagerProbe
from task_manager.testing.process import LaunchTaskManager, action_task, taskctl
from task_manager.testing.servers import ScriptedActionServer, ScriptedGoal

TIMEOUT_SEC = 15.0
DURATION = r'\d+\.\d s'  # how taskctl shows a time under a minute
CLOCK = r'(\d{4}-\d\d-\d\d )?\d\d:\d\d:\d\d'  # how taskctl shows a time (date: not today)
# The operator keeps the task paused this long: the scenario (a pause long enough to tell
# apart from the rounding of stamps), not a synchronisation.
PAUSED_FOR_SEC = 0.1
ONE_MS = timedelta(milliseconds=1)
# A pause's length from its two stamps (each rounded to a microsecond) vs its paused_sec
ROUNDING = timedelta(microseconds=1)
ACTIVE_FIELDS = {
    'task_id', 'task_name', 'status', 'source', 'mission_id', 'received_at', 'started_at',
    'duration_sec', 'paused_sec', 'pauses', 'priority', 'queue_position', 'attempt', 'prompt',
}  # fmt: skip
CANNOT_PAUSE = (
    'task snap (photo) cannot be paused: its entry declares pause: none (the default); '
    'pause: restart pauses an action task by cancelling its goal and sending it again on resume'
)


def _succeed(goal: ScriptedGoal) -> None:
    goal.succeed(Fibonacci.Result(sequence=[goal.request.order]))


def _launch_pausable(
    ros: RosHarness, launch: LaunchTaskManager, prefix: str
) -> tuple[TaskManagerProbe, ScriptedActionServer, ScriptedActionServer]:
    """`navigate` (pause: restart) and `photo` (pause: none); goals run until the test ends
    them."""
    nav = ScriptedActionServer(ros.node, Fibonacci, f'{prefix}/nav')
    photo = ScriptedActionServer(ros.node, Fibonacci, f'{prefix}/photo')
    tm = launch(
        {
            'nav': action_task('navigate', f'{prefix}/nav', pause='restart'),
            'photo': action_task('photo', f'{prefix}/photo'),
        }
    )
    return tm, nav, photo


def _launch_instant(ros: RosHarness, launch: LaunchTaskManager, prefix: str) -> TaskManagerProbe:
    """`math/fib` (reentrant), whose goals succeed at once."""
    ScriptedActionServer(ros.node, Fibonacci, f'{prefix}/fib', on_goal=_succeed)
    probe: TaskManagerProbe = launch(
        {'fib': action_task('math/fib', f'{prefix}/fib', reentrant=True)}
    )
    return probe


def _line_with(text: str, output: str) -> str:
    return next(line for line in output.splitlines() if text in line)


def _rows(output: str) -> list[dict[str, Any]]:
    return [json.loads(line) for line in output.splitlines()]


def _moment(text: str) -> datetime:
    return datetime.fromisoformat(text)


def test_taskctl_pauses_and_resumes_by_id_with_a_line_per_id(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, nav, photo = _launch_pausable(ros, launch_task_manager, topic_prefix)
    drive = tm.send('navigate', {'order': 7}, task_id='drive')
    snap = tm.send('photo', {'order': 1}, task_id='snap')
    first, shot = nav.wait_for_goals(1, TIMEOUT_SEC)[0], photo.wait_for_goals(1, TIMEOUT_SEC)[0]
    tm.wait_active(lambda tasks: {('drive', 'IN_PROGRESS'), ('snap', 'IN_PROGRESS')} <= set(tasks))

    paused = taskctl('pause', 'drive', 'snap', 'nosuch', '--source', 'operator')
    tm.wait_active(lambda tasks: ('drive', 'PAUSED') in tasks, 'drive PAUSED')
    active = taskctl('active')
    active_json = taskctl('active', '--json')
    resumed = taskctl('resume', 'drive')
    second = nav.wait_for_goals(2, TIMEOUT_SEC)[1]
    not_paused = taskctl('resume', 'drive')
    second.succeed(Fibonacci.Result(sequence=[7]))
    shot.succeed(Fibonacci.Result(sequence=[1]))
    drive_end, snap_end = tm.result_of(drive), tm.result_of(snap)
    history = taskctl('history', '--task', 'navigate', '--json')

    assert paused.returncode == 1
    assert paused.stdout == 'drive  paused\n'
    assert paused.stderr.splitlines() == [
        f'ERROR: {CANNOT_PAUSE}',
        "ERROR: no active task 'nosuch' to pause",
    ]
    assert first.cancel_requested.is_set() and first.ended.wait(TIMEOUT_SEC)  # paused by restart
    assert active.returncode == 0, active.stderr
    assert re.search(
        rf'drive\W+navigate\W+PAUSED\W+test\W+{DURATION}', _line_with(' drive ', active.stdout)
    )
    assert re.search(
        rf'snap\W+photo\W+IN_PROGRESS\W+test\W+{DURATION}', _line_with(' snap ', active.stdout)
    )
    assert active_json.returncode == 0, active_json.stderr
    as_json = {row['task_id']: row for row in _rows(active_json.stdout)}
    assert set(as_json) == {'drive', 'snap'}
    assert set(as_json['drive']) == ACTIVE_FIELDS
    assert (as_json['drive']['status'], as_json['snap']['status']) == ('PAUSED', 'IN_PROGRESS')
    (open_pause,) = as_json['drive']['pauses']
    assert (open_pause['paused_by'], open_pause['resumed_at'], open_pause['resumed_by']) == (
        'operator', None, '',
    )  # fmt: skip
    assert as_json['snap']['pauses'] == [] and as_json['snap']['paused_sec'] == 0.0
    assert (resumed.returncode, resumed.stdout, resumed.stderr) == (0, 'drive  resumed\n', '')
    assert second.request.order == 7  # the same goal, sent again
    assert not_paused.returncode == 1 and not_paused.stdout == ''
    assert not_paused.stderr.splitlines() == [
        'ERROR: task drive (navigate) is not paused (it is IN_PROGRESS); '
        'only a paused task can be resumed'
    ]
    assert (drive_end.result.task_status, snap_end.result.task_status) == ('DONE', 'DONE')
    assert json.loads(drive_end.result.task_result) == {'sequence': [7]}
    assert history.returncode == 0, history.stderr
    (stored,) = _rows(history.stdout)
    (pause,) = stored['pauses']
    assert set(pause) == {'paused_at', 'paused_by', 'resumed_at', 'resumed_by'}
    assert (pause['paused_at'], pause['paused_by']) == (open_pause['paused_at'], 'operator')
    assert pause['resumed_by'] == 'CLI' and pause['paused_at'] < pause['resumed_at']
    paused_for = _moment(pause['resumed_at']) - _moment(pause['paused_at'])
    assert abs(timedelta(seconds=stored['paused_sec']) - paused_for) <= 2 * ROUNDING


class EventLog:
    """An on_task_event callback; the test waits on what it got."""

    def __init__(self) -> None:
        self.events: list[TaskEvent] = []
        self._changed = threading.Condition()

    def __call__(self, event: TaskEvent) -> None:
        with self._changed:
            self.events.append(event)
            self._changed.notify_all()

    def wait_for(self, done: Callable[[list[TaskEvent]], bool], what: str) -> list[TaskEvent]:
        with self._changed:
            if not self._changed.wait_for(lambda: done(self.events), TIMEOUT_SEC):
                raise WaitTimeoutError(f'{what} not seen within {TIMEOUT_SEC} s')
            return list(self.events)


def test_the_client_pauses_and_resumes_and_the_result_leaves_out_the_time_paused(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, nav, _ = _launch_pausable(ros, launch_task_manager, topic_prefix)
    log = EventLog()
    with TaskManagerClient('test_pause_client', timeout_sec=TIMEOUT_SEC) as client:
        client.wait_until_available(events=True)
        client.on_task_event(log)
        handle = client.start_task('navigate', {'order': 4}, task_id='walk', source='UI')
        nav.wait_for_goals(1, TIMEOUT_SEC)
        tm.wait_in_progress('walk')

        paused = client.pause(['walk'], source='operator')
        (while_paused,) = client.task_states(['walk'])
        time.sleep(PAUSED_FOR_SEC)  # the scenario: see PAUSED_FOR_SEC
        resumed = client.resume(['walk'], source='operator')
        nav.wait_for_goals(2, TIMEOUT_SEC)[1].succeed(Fibonacci.Result(sequence=[4]))
        result = handle.result(TIMEOUT_SEC)
        events = log.wait_for(
            lambda got: any(
                e.task.task_id == 'walk' and e.kind is TaskEventKind.ENDED for e in got
            ),
            'the ENDED event of walk',
        )
        (stored,) = client.task_states(['walk'])  # from the history, now that it ended

    assert paused.ok and (paused.task_name, paused.source) == ('system/pause', 'operator')
    assert paused.result == {'success': True, 'successful_pauses': ['walk'], 'errors': []}
    assert resumed.ok and resumed.task_name == 'system/resume'
    assert resumed.result == {'success': True, 'successful_resumes': ['walk'], 'errors': []}
    assert while_paused.status is TaskStatus.PAUSED
    (open_pause,) = while_paused.pauses
    assert (open_pause.paused_by, open_pause.resumed_at) == ('operator', None)
    now = datetime.now(open_pause.paused_at.tzinfo)  # the clock stops while paused
    assert while_paused.elapsed(now) == while_paused.elapsed(now + timedelta(hours=1))
    assert (result.status, result.result) == (TaskStatus.DONE, {'sequence': [4]})
    assert stored.sequence > 0 and stored.paused >= timedelta(seconds=PAUSED_FOR_SEC)
    assert abs(result.paused - stored.paused) <= ROUNDING
    assert stored.started_at is not None and stored.ended_at is not None
    assert result.duration is not None
    assert abs(result.duration - (stored.ended_at - stored.started_at - stored.paused)) <= ONE_MS
    walk = [e for e in events if e.task.task_id == 'walk' and e.kind is not TaskEventKind.FEEDBACK]
    kinds = [e.kind for e in walk]
    assert kinds[kinds.index(TaskEventKind.PAUSED) :] == [
        TaskEventKind.PAUSED,
        TaskEventKind.RESUMED,
        TaskEventKind.ENDED,
    ]
    assert [e.task.status for e in walk[-3:]] == [
        TaskStatus.PAUSED,
        TaskStatus.IN_PROGRESS,
        TaskStatus.DONE,
    ]
    assert [(p.paused_by, p.resumed_by) for p in walk[-1].task.pauses] == [('operator', 'operator')]


def test_taskctl_schedules_lists_disables_enables_and_removes(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm = _launch_instant(ros, launch_task_manager, topic_prefix)

    added = taskctl(
        'schedule', 'add', 'math/fib', '{"order": 3}', '--id', 'tick', '--every', '0.2s',
        '--max-runs', '2',
    )  # fmt: skip
    bad_cron = taskctl('schedule', 'add', 'math/fib', '{}', '--cron', '61 * * * *')
    runs = [tm.wait_result_message(f'tick-run-{n}') for n in (1, 2)]
    disabled = taskctl('schedule', 'disable', 'tick')
    listed = taskctl('schedule', 'list', '--json')
    enabled = taskctl('schedule', 'enable', 'tick')
    removed = taskctl('schedule', 'remove', 'tick', 'nosuch')
    emptied = taskctl('schedule', 'list', '--json')

    assert added.returncode == 0, added.stderr
    assert re.fullmatch(rf'tick  next run {CLOCK}\n', added.stdout), added.stdout
    assert (bad_cron.returncode, bad_cron.stdout) == (1, '')
    (why,) = bad_cron.stderr.splitlines()
    assert why.startswith(
        "task_data_parsing_failed: field 'cron': cron '61 * * * *' is not a cron expression "
        "(5 fields: minute hour day-of-month month day-of-week, e.g. '0 2 * * *')"
    ), why
    assert [(r.task_id, r.task_name, r.task_status, r.source) for r in runs] == [
        ('tick-run-1', 'math/fib', 'DONE', 'schedule:tick'),
        ('tick-run-2', 'math/fib', 'DONE', 'schedule:tick'),
    ]
    assert json.loads(runs[1].task_result) == {'sequence': [3]}
    assert listed.returncode == 0, listed.stderr
    (tick,) = _rows(listed.stdout)
    assert {
        'schedule_id': 'tick',
        'task_name': 'math/fib',
        'task_data': {'order': 3},
        'created_by': 'CLI',
        'period_sec': 0.2,
        'max_runs': 2,
        'enabled': False,
        'run_count': 2,
        'next_run': None,
        'last_task_id': 'tick-run-2',
        'last_status': 'DONE',
    }.items() <= tick.items()
    assert (disabled.returncode, disabled.stdout) == (0, 'tick  disabled\n')
    assert (enabled.returncode, enabled.stdout) == (0, 'tick  enabled\n')
    assert removed.returncode == 1
    assert removed.stdout == 'tick  removed\n'
    assert removed.stderr.splitlines() == ["ERROR: no schedule 'nosuch'"]
    assert (emptied.returncode, emptied.stdout) == (0, '')
    # enabling a schedule that reached max_runs starts no third run
    assert len(tm.results_for('tick-run-2')) == 1 and tm.results_for('tick-run-3') == []


def test_taskctl_schedules_a_mission_from_a_file_to_run_once(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str, tmp_path: Path
) -> None:
    tm = _launch_instant(ros, launch_task_manager, topic_prefix)
    plan = tmp_path / 'patrol.yaml'
    plan.write_text(
        'subtasks:\n'
        '  - {task_name: math/fib, task_data: {order: 1}, task_id: leg-1}\n'
        '  - {task_name: math/fib, task_data: {order: 2}, task_id: leg-2}\n'
    )

    added = taskctl('schedule', 'add', '--mission', str(plan), '--in', '0.3s', '--id', 'patrol')
    run = tm.wait_result_message('patrol-run-1')

    assert added.returncode == 0, added.stderr
    assert re.fullmatch(rf'patrol  next run {CLOCK}\n', added.stdout), added.stdout
    assert (run.task_name, run.task_status, run.source) == (
        'system/mission',
        'DONE',
        'schedule:patrol',
    )
    rows = json.loads(run.task_result)['mission_results']
    assert [(r['task_id'], r['task_status']) for r in rows] == [
        ('leg-1', 'DONE'),
        ('leg-2', 'DONE'),
    ]
