"""taskctl driven as a user would: a subprocess against a real node and real servers."""

import json
import re
import signal
import subprocess
import time
from pathlib import Path

from test_msgs.action import Fibonacci

from task_manager.testing.harness import RosHarness
from task_manager.testing.probe import TaskManagerProbe
from task_manager.testing.process import (
    TASKCTL,
    TASKCTL_TIMEOUT_SEC,
    LaunchTaskManager,
    action_task,
    taskctl,
)
from task_manager.testing.servers import ScriptedActionServer, ScriptedGoal

FAIL, HOLD = 99, 50  # Fibonacci orders the scripted server aborts / keeps running


def _decide(goal: ScriptedGoal) -> None:
    if goal.request.order == FAIL:
        goal.abort()
    elif goal.request.order < HOLD:
        goal.succeed(Fibonacci.Result(sequence=[goal.request.order]))


def _launch(ros: RosHarness, launch: LaunchTaskManager, prefix: str) -> TaskManagerProbe:
    ScriptedActionServer(ros.node, Fibonacci, f'{prefix}/fib', on_goal=_decide)
    probe: TaskManagerProbe = launch(
        {'fib': action_task('math/fib', f'{prefix}/fib', reentrant=True, cancel_on_stop=True)}
    )
    return probe


def test_start_waits_and_exits_by_status(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    _launch(ros, launch_task_manager, topic_prefix)

    done = taskctl('start', 'math/fib', '{"order": 3}', '--id', 'cli-1', '--source', 'shell')
    failed = taskctl('start', 'math/fib', '{"order": 99}')
    unknown = taskctl('start', 'no/such', '{}')
    bad_json = taskctl('start', 'math/fib', '{order')

    assert done.returncode == 0, done.stderr
    printed = json.loads(done.stdout)
    assert (printed['task_id'], printed['status'], printed['source']) == ('cli-1', 'DONE', 'shell')
    assert printed['result'] == {'sequence': [3]}
    assert failed.returncode == 1 and json.loads(failed.stdout)['status'] == 'ERROR'
    assert unknown.returncode == 1
    assert json.loads(unknown.stdout)['error_code'] == 'unknown_task'
    # why, on stderr, in one line (the same text as the result's `error`)
    why = (
        "unknown task 'no/such'; declared tasks: math/fib, system/cancel_task, "
        'system/cancel_tasks, system/confirm, system/enable_schedule, system/mission, '
        'system/pause, system/reprioritize, system/resume, system/schedule, system/stop, '
        'system/unschedule, system/wait'
    )
    assert json.loads(unknown.stdout)['result'] == {'error': why}
    assert unknown.stderr.strip().splitlines()[-1] == f'unknown_task: {why}'
    assert 'error' not in done.stderr
    assert bad_json.returncode == 2 and 'not valid JSON' in bad_json.stderr


def test_start_without_waiting_cancel_and_the_canceled_exit_code(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm = _launch(ros, launch_task_manager, topic_prefix)
    waiting = subprocess.Popen(
        [TASKCTL, 'start', 'math/fib', '{"order": 50}', '--id', 'held'],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    tm.wait_in_progress('held')
    background = taskctl('start', 'math/fib', '{"order": 51}', '--no-wait')
    other_id = background.stdout.strip()
    tm.wait_in_progress(other_id)

    cancelled = taskctl('cancel', 'held', 'ghost')
    stopped = taskctl('stop')

    assert background.returncode == 0 and other_id
    assert cancelled.returncode == 0, cancelled.stderr
    assert json.loads(cancelled.stdout)['result']['successful_cancels'] == ['held', 'ghost']
    assert waiting.wait(TASKCTL_TIMEOUT_SEC) == 3  # CANCELED
    assert waiting.stdout is not None
    assert json.loads(waiting.stdout.read())['status'] == 'CANCELED'
    assert stopped.returncode == 0
    assert tm.wait_result_message(other_id).task_status == 'CANCELED'


def test_mission_from_a_yaml_file(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str, tmp_path: Path
) -> None:
    _launch(ros, launch_task_manager, topic_prefix)
    good = tmp_path / 'good.yaml'
    good.write_text(
        'subtasks:\n'
        '  - {task_name: math/fib, task_data: {order: 1}, task_id: s1}\n'
        '  - {task_name: math/fib, task_data: {order: 99}, allow_skipping: true, task_id: s2}\n'
        '  - {task_name: math/fib, task_data: \'{"order": 2}\', task_id: s3}\n'
    )
    failing = tmp_path / 'failing.json'
    failing.write_text(json.dumps([{'task_name': 'math/fib', 'task_data': {'order': 99}}]))

    done = taskctl('mission', str(good))
    failed = taskctl('mission', str(failing))

    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)['source'] == 'CLI'
    rows = json.loads(done.stdout)['result']['mission_results']
    assert [(r['task_id'], r['task_status'], r['skipped']) for r in rows] == [
        ('s1', 'DONE', False),
        ('s2', 'ERROR', True),
        ('s3', 'DONE', False),
    ]
    assert failed.returncode == 1


def test_active_results_and_tasks(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm = _launch(ros, launch_task_manager, topic_prefix)
    tm.run('math/fib', {'order': 4}, task_id='finished-earlier')
    tm.send('math/fib', {'order': 50}, task_id='running-now')
    tm.wait_in_progress('running-now')

    active = taskctl('active')
    active_json = taskctl('active', '--json')
    results = taskctl('results', '--json')
    tasks = taskctl('tasks')
    tasks_json = taskctl('tasks', '--json')

    assert active.returncode == 0 and 'running-now' in active.stdout
    assert active_json.returncode == 0, active_json.stderr
    (running,) = [json.loads(line) for line in active_json.stdout.splitlines()]
    stamps = {key: running.pop(key) for key in ('received_at', 'started_at', 'duration_sec')}
    assert running == {
        'task_id': 'running-now',
        'task_name': 'math/fib',
        'status': 'IN_PROGRESS',
        'source': 'test',
        'mission_id': '',
        'paused_sec': 0.0,
        'pauses': [],
        'priority': 0,
        'queue_position': 0,
        'attempt': 1,
        'prompt': '',  # a waiting system/confirm's prompt
    }
    assert stamps['received_at'] <= stamps['started_at'] and stamps['duration_sec'] >= 0
    lines = [json.loads(line) for line in results.stdout.splitlines()]
    assert {'task_id': 'finished-earlier', 'status': 'DONE'}.items() <= lines[-1].items()
    assert tasks.returncode == 0
    for name in ('math/fib', 'system/mission', 'system/wait', 'system/stop'):
        assert name in tasks.stdout
    assert tasks_json.returncode == 0, tasks_json.stderr
    declared = [json.loads(line) for line in tasks_json.stdout.splitlines()]
    assert declared[0] == {
        'task_name': 'math/fib',
        'msg_interface': 'test_msgs.action.Fibonacci',
        'topic': f'{topic_prefix}/fib',
        'blocking': False,
        'cancel_on_stop': True,
        'reentrant': True,
        'cancel_reported_as_success': False,
        'cancel_timeout_sec': 5.0,
    }
    assert {'system/mission', 'system/wait', 'system/stop'} <= {d['task_name'] for d in declared}


DURATION = r'\d+\.\d s'  # how taskctl shows a time under a minute


def _line_with(text: str, output: str) -> str:
    return next(line for line in output.splitlines() if text in line)


def test_active_and_results_show_how_long_tasks_run_and_when_they_ended(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm = _launch(ros, launch_task_manager, topic_prefix)
    tm.run('no/such', {}, task_id='refused')
    tm.run('math/fib', {'order': 4}, task_id='finished')
    tm.send('math/fib', {'order': 50}, task_id='held')
    tm.wait_in_progress('held')

    active = taskctl('active')
    results = taskctl('results', '--limit', '2')
    as_json = taskctl('results', '--last', '1', '--json')  # --limit's old name still works

    assert active.returncode == 0, active.stderr
    assert 'running for' in active.stdout
    held_row = _line_with(' held ', active.stdout)
    assert re.search(f'held .*IN_PROGRESS .* {DURATION}', held_row), active.stdout
    assert results.returncode == 0, results.stderr
    assert re.fullmatch(
        rf"DONE  math/fib  finished  from 'test'  ended \d\d:\d\d:\d\d after {DURATION}  "
        r'\{"sequence": \[4\]\}',
        _line_with('finished', results.stdout),
    )
    assert 'never started' in _line_with('refused', results.stdout)
    (row,) = [json.loads(line) for line in as_json.stdout.splitlines()]
    assert row['task_id'] == 'finished' and 0 <= row['duration_sec'] < TASKCTL_TIMEOUT_SEC
    assert row['received_at'] <= row['started_at'] <= row['ended_at']  # ISO 8601, one zone


def test_mission_shows_each_subtasks_progress(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str, tmp_path: Path
) -> None:
    _launch(ros, launch_task_manager, topic_prefix)
    plan = tmp_path / 'mission.yaml'
    plan.write_text(
        'subtasks:\n'
        '  - {task_name: math/fib, task_data: {order: 1}, task_id: s1}\n'
        '  - {task_name: math/fib, task_data: {order: 99}, allow_skipping: true, task_id: s2}\n'
        '  - {task_name: math/fib, task_data: {order: 2}, task_id: s3}\n'
    )

    failing = tmp_path / 'failing.yaml'
    failing.write_text(
        '- {task_name: math/fib, task_data: {order: 99}, task_id: f1}\n'
        '- {task_name: math/fib, task_data: {order: 1}, task_id: f2}\n'
    )

    done = taskctl('mission', str(plan), '--id', 'm1', env={'COLUMNS': '160'})
    failed = taskctl('mission', str(failing), env={'COLUMNS': '160'})

    assert done.returncode == 0, done.stderr
    # not a terminal: the table is drawn once, at the end, on stderr
    assert re.search(f'mission m1  DONE  {DURATION}', done.stderr), done.stderr
    assert re.search(f's1 .* DONE .* {DURATION}', _line_with(' s1 ', done.stderr))
    assert 'ERROR (skipped)' in _line_with(' s2 ', done.stderr)
    assert re.search(f's3 .* DONE .* {DURATION}', _line_with(' s3 ', done.stderr))
    assert json.loads(done.stdout)['task_id'] == 'm1'
    assert failed.returncode == 1
    assert 'ERROR' in _line_with(' f1 ', failed.stderr)
    assert 'not run' in _line_with(' f2 ', failed.stderr)


def test_no_task_manager_is_reported_within_the_bound() -> None:
    started = time.monotonic()

    missing = taskctl('--timeout', '1', 'start', 'math/fib', '{}')

    assert missing.returncode == 4
    assert missing.stderr.startswith('TaskManagerUnavailable: no Task Manager answered')
    assert time.monotonic() - started < 10.0


def _until_line(process: subprocess.Popen[str], text: str) -> list[str]:
    """Read the process's output until a line contains `text` (bounded by the test timeout)."""
    assert process.stdout is not None
    lines = []
    for line in process.stdout:
        lines.append(line)
        if text in line:
            return lines
    raise AssertionError(f'{text!r} never printed; output: {"".join(lines)}')


def test_watch_and_follow_show_changes_until_ctrl_c(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm = _launch(ros, launch_task_manager, topic_prefix)
    tm.run('math/fib', {'order': 1}, task_id='kept')
    watching = subprocess.Popen(
        [TASKCTL, 'active', '--watch'], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )
    following = subprocess.Popen(
        [TASKCTL, 'results', '--follow', '--limit', '0', '--json'],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        _until_line(watching, 'active tasks (0)')  # connected: the table is drawn
        _until_line(following, '"kept"')  # connected: the kept results are printed

        tm.send('math/fib', {'order': 50}, task_id='watched')
        seen_active = _until_line(watching, 'watched')
        tm.run('math/fib', {'order': 1}, task_id='followed')
        seen_result = _until_line(following, '"followed"')
        # One after the other: Fast DDS 3.2 can deadlock destroying a participant while
        # another's endpoints vanish (set_listener spins; on_reader_discovery waits).
        codes = []
        for process in (watching, following):
            process.send_signal(signal.SIGINT)
            codes.append(process.wait(TASKCTL_TIMEOUT_SEC))
    finally:
        for process in (watching, following):
            if process.poll() is None:
                process.kill()
                process.wait()

    assert any('IN_PROGRESS' in line for line in seen_active)
    assert json.loads(seen_result[-1])['status'] == 'DONE'
    assert codes == [0, 0]
