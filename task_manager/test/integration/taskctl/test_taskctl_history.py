"""taskctl history and taskctl stats as a user runs them: subprocesses against a real node."""

import json
import re
from typing import Any

from test_msgs.action import Fibonacci

from task_manager.testing.harness import RosHarness
from task_manager.testing.probe import TaskManagerProbe
from task_manager.testing.process import (
    LaunchTaskManager,
    action_task,
    taskctl,
)
from task_manager.testing.servers import ScriptedActionServer, ScriptedGoal

FAIL = 99  # the Fibonacci order the scripted server aborts
DURATION = r'\d+\.\d s'  # how taskctl shows a time under a minute
# The fields of `taskctl history --json` (docs/taskctl.md)
HISTORY_FIELDS = {
    'task_id', 'task_name', 'status', 'error_code', 'source', 'result', 'received_at',
    'started_at', 'ended_at', 'duration_sec', 'paused_sec', 'mission_id', 'sequence', 'pauses',
}  # fmt: skip


def _decide(goal: ScriptedGoal) -> None:
    if goal.request.order == FAIL:
        goal.abort()
    else:
        goal.succeed(Fibonacci.Result(sequence=[goal.request.order]))


def _launch(ros: RosHarness, launch: LaunchTaskManager, prefix: str) -> TaskManagerProbe:
    ScriptedActionServer(ros.node, Fibonacci, f'{prefix}/fib', on_goal=_decide)
    probe: TaskManagerProbe = launch(
        {'fib': action_task('math/fib', f'{prefix}/fib', reentrant=True)}
    )
    return probe


def _rows(output: str) -> list[dict[str, Any]]:
    return [json.loads(line) for line in output.splitlines()]


def _run_some(ros: RosHarness, launch: LaunchTaskManager, prefix: str) -> None:
    """fib: 3 DONE (2 from CLOUD), 1 ERROR; an unknown task; a mission of two fibs."""
    tm = _launch(ros, launch, prefix)
    tm.run('math/fib', {'order': 1}, task_id='h1', source='CLI')
    tm.run('math/fib', {'order': 2}, task_id='h2', source='CLOUD')
    tm.run('math/fib', {'order': 3}, task_id='h3', source='CLOUD')
    tm.run('math/fib', {'order': FAIL}, task_id='h-failed', source='CLI')
    tm.run('no/such', {}, task_id='h-unknown', source='CLI')
    subtasks = [
        {'task_id': f'h-sub{n}', 'task_name': 'math/fib', 'task_data': json.dumps({'order': n})}
        for n in (4, 5)
    ]
    assert tm.run('system/mission', {'subtasks': subtasks}, task_id='h-m').task_status == 'DONE'


def test_history_filters_by_task_status_source_mission_and_limit(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    _run_some(ros, launch_task_manager, topic_prefix)

    fib = taskctl('history', '--task', 'math/fib', '--since', '1h', '--json')
    done_cloud = taskctl('history', '--status', 'done', '--source', 'CLOUD', '--json')
    errors = taskctl('history', '--status', 'ERROR', '--json')
    mission = taskctl('history', '--mission', 'h-m', '--oldest-first', '--json')
    newest_two = taskctl('history', '--limit', '2', '--json')
    human = taskctl('history', '--task', 'math/fib', '--source', 'CLOUD')

    for run in (fib, done_cloud, errors, mission, newest_two, human):
        assert run.returncode == 0, run.stderr
    rows = _rows(fib.stdout)
    assert [r['task_id'] for r in rows] == ['h-sub5', 'h-sub4', 'h-failed', 'h3', 'h2', 'h1']
    sequences = [r['sequence'] for r in rows]
    assert sequences == sorted(sequences, reverse=True) and len(set(sequences)) == len(rows)
    h3 = next(r for r in rows if r['task_id'] == 'h3')
    assert set(h3) == HISTORY_FIELDS
    expected = {
        'status': 'DONE',
        'error_code': '',
        'source': 'CLOUD',
        'mission_id': '',
        'result': {'sequence': [3]},
        'paused_sec': 0.0,
        'pauses': [],
    }
    assert expected.items() <= h3.items()
    assert h3['received_at'] <= h3['started_at'] <= h3['ended_at'] and h3['duration_sec'] >= 0
    assert [r['task_id'] for r in _rows(done_cloud.stdout)] == ['h3', 'h2']
    assert {r['task_id'] for r in _rows(errors.stdout)} >= {'h-failed', 'h-unknown'}
    assert all(r['status'] == 'ERROR' for r in _rows(errors.stdout))
    assert [(r['task_id'], r['mission_id']) for r in _rows(mission.stdout)] == [
        ('h-sub4', 'h-m'),
        ('h-sub5', 'h-m'),
    ]
    assert [r['task_id'] for r in _rows(newest_two.stdout)] == ['h-m', 'h-sub5']
    lines = human.stdout.splitlines()
    assert len(lines) == 2
    assert re.fullmatch(
        rf"DONE  math/fib  h3  from 'CLOUD'  ended \d\d:\d\d:\d\d after {DURATION}  "
        r'\{"sequence": \[3\]\}',
        lines[0],
    ), human.stdout


def test_stats_per_task_as_json_and_as_a_table(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    _run_some(ros, launch_task_manager, topic_prefix)

    as_json = taskctl('stats', '--json')
    cli_only = taskctl('stats', '--since', '30m', '--source', 'CLI', '--json')
    table = taskctl('stats', '--since', '1d')

    for run in (as_json, cli_only, table):
        assert run.returncode == 0, run.stderr
    per_task = {r['task_name']: r for r in _rows(as_json.stdout)}
    fib = per_task['math/fib']
    assert (fib['count'], fib['done_count'], fib['started_count']) == (6, 5, 6)
    assert fib['success_rate'] == 5 / 6
    assert 0 <= fib['median_duration_sec'] <= fib['p95_duration_sec']
    unknown = per_task['no/such']
    assert (unknown['count'], unknown['success_rate'], unknown['median_duration_sec']) == (
        1, 0.0, None,
    )  # fmt: skip
    assert per_task['system/mission']['count'] == 1
    cli = {r['task_name']: r for r in _rows(cli_only.stdout)}
    assert (cli['math/fib']['count'], cli['math/fib']['done_count']) == (2, 1)
    assert 'system/mission' not in cli
    assert 'tasks ended in the last 1d' in table.stdout
    for column in ('task', 'count', 'success %', 'median', 'p95'):
        assert column in table.stdout
    fib_row = next(line for line in table.stdout.splitlines() if 'math/fib' in line)
    assert re.search(rf'math/fib\W+6\W+83\.3\W+{DURATION}\W+{DURATION}', fib_row), table.stdout


def test_a_bad_span_or_status_is_a_usage_error() -> None:
    wide = {'COLUMNS': '200'}  # the usage error is one line
    bad_span = taskctl('history', '--since', '2x', env=wide)
    bad_status = taskctl('history', '--status', 'IN_PROGRESS', env=wide)
    bad_stats = taskctl('stats', '--since', 'yesterday')

    assert bad_span.returncode == bad_status.returncode == bad_stats.returncode == 2
    assert "'2x' is not a span of time" in bad_span.stderr
    assert 'DONE, ERROR, CANCELED' in bad_status.stderr
