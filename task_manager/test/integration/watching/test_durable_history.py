"""The durable history over real processes: nothing forgotten across a SIGKILL and a restart."""

import json
import sqlite3
from collections import Counter
from pathlib import Path

from rclpy.client import Client
from task_manager_msgs.srv import GetTaskResults, GetTaskStates, QueryTaskHistory
from test_msgs.action import Fibonacci

from task_manager.rclpy_tools.server_wait import wait_until_ready
from task_manager.testing.harness import RosHarness, wait_for_future
from task_manager.testing.probe import TaskManagerProbe
from task_manager.testing.process import (
    LaunchTaskManager,
    NodeProcess,
    action_task,
    write_params_file,
)
from task_manager.testing.servers import ScriptedActionServer, ScriptedGoal

TIMEOUT_SEC = 20.0
HOLD = 50  # Fibonacci orders at or above it are held by the server: the task keeps running
ENDED_COUNT, RUNNING_COUNT = 40, 6
FULL_DISK_BYTES = 256 * 1024
FULL_DISK_TASKS = 120


def _decide(goal: ScriptedGoal) -> None:
    if goal.request.order < HOLD:
        goal.succeed(Fibonacci.Result(sequence=[goal.request.order]))


def _launch(
    launch: LaunchTaskManager, prefix: str, history: Path, **parameters: object
) -> TaskManagerProbe:
    probe: TaskManagerProbe = launch(
        {'fib': action_task('fib', f'{prefix}/fib', reentrant=True)},
        history_path=str(history),
        results_history_size=10_000,
        **parameters,
    )
    return probe


def test_a_killed_node_forgets_nothing_and_closes_its_running_tasks_once(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str, tmp_path: Path
) -> None:
    ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/fib', on_goal=_decide)
    history = tmp_path / 'history.sqlite'
    first = _launch(launch_task_manager, topic_prefix, history)
    running = [f'run-{n}' for n in range(RUNNING_COUNT)]
    for task_id in running:
        first.send('fib', {'order': HOLD}, task_id=task_id)
    handles = [first.send('fib', {'order': n}, task_id=f'end-{n}') for n in range(ENDED_COUNT)]
    for handle in handles[: ENDED_COUNT // 2]:  # half of the burst has surely ended
        first.result_of(handle)
    first.wait_active(lambda tasks: all((t, 'IN_PROGRESS') in tasks for t in running))

    first.process.kill()  # type: ignore[attr-defined]  # mid-burst, as a power loss would
    second = _launch(launch_task_manager, topic_prefix, history)

    # published once a results subscriber has matched: the first probe's still listens
    closed = [first.wait_result_message(task_id) for task_id in running]
    assert {(m.task_status, m.error_code) for m in closed} == {('ERROR', '')}
    assert all('stopped while this task ran' in json.loads(m.task_result)['error'] for m in closed)
    rows = (
        sqlite3.connect(history)
        .execute('SELECT task_id, status, result, sequence FROM tasks')
        .fetchall()
    )
    ours = set(running) | {f'end-{n}' for n in range(ENDED_COUNT)}
    by_id = Counter(task_id for task_id, *_ in rows if task_id in ours)
    assert max(by_id.values()) == 1  # no request stored twice
    sequences = [sequence for *_, sequence in rows]
    assert None not in sequences and len(set(sequences)) == len(sequences)
    stored = {task_id: (status, result) for task_id, status, result, _ in rows}
    for n in range(ENDED_COUNT // 2):  # every task that had ended, with its result
        assert stored[f'end-{n}'] == ('DONE', json.dumps({'sequence': [n]}, separators=(',', ':')))
    for task_id in running:
        assert stored[task_id][0] == 'ERROR'
    # each running task is closed once: a third start finds nothing left to close
    assert first.results_for(running[0]) == [closed[0]]
    assert second.run('fib', {'order': 1}).task_status == 'DONE'


def test_results_and_states_are_served_from_the_history_after_a_restart(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str, tmp_path: Path
) -> None:
    ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/fib', on_goal=_decide)
    history = tmp_path / 'history.sqlite'
    first = _launch(launch_task_manager, topic_prefix, history)
    first.run('fib', {'order': 3}, task_id='before', source='CLOUD')
    first.process.stop()  # type: ignore[attr-defined]
    _launch(launch_task_manager, topic_prefix, history)
    results: Client[GetTaskResults.Request, GetTaskResults.Response] = ros.node.create_client(
        GetTaskResults, '/task_manager/get_task_results'
    )
    states: Client[GetTaskStates.Request, GetTaskStates.Response] = ros.node.create_client(
        GetTaskStates, '/task_manager/get_task_states'
    )
    assert wait_until_ready(results.service_is_ready, TIMEOUT_SEC)
    assert wait_until_ready(states.service_is_ready, TIMEOUT_SEC)

    kept = wait_for_future(
        results.call_async(GetTaskResults.Request(max_results=0)), TIMEOUT_SEC, 'results'
    ).results
    state = wait_for_future(
        states.call_async(GetTaskStates.Request(task_ids=['before'])), TIMEOUT_SEC, 'states'
    ).tasks

    assert [(r.task_id, r.task_status, r.source) for r in kept if r.task_id == 'before'] == [
        ('before', 'DONE', 'CLOUD')
    ]
    assert [(s.task_id, s.task_status, json.loads(s.task_result)) for s in state] == [
        ('before', 'DONE', {'sequence': [3]})
    ]
    assert state[0].sequence > 0 and state[0].ended.sec > 0


def test_a_corrupt_history_is_moved_aside_and_the_node_starts(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str, tmp_path: Path
) -> None:
    ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/fib', on_goal=_decide)
    history = tmp_path / 'history.sqlite'
    history.write_bytes(b'not a database, a robot must start anyway' * 100)

    tm = _launch(launch_task_manager, topic_prefix, history)

    warning = tm.process.wait_for_log(r'moved it to', 1.0)  # type: ignore[attr-defined]
    aside = Path(warning.split('moved it to ')[1].split(' and started')[0])
    assert aside.read_bytes().startswith(b'not a database')
    assert tm.run('fib', {'order': 2}, task_id='fresh').task_status == 'DONE'
    stored = sqlite3.connect(history).execute('SELECT task_id FROM tasks').fetchall()
    assert ('fresh',) in stored


def test_the_history_is_queried_by_filters_and_kept_within_its_limits(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str, tmp_path: Path
) -> None:
    ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/fib', on_goal=_decide)
    history = tmp_path / 'history.sqlite'
    first = _launch(launch_task_manager, topic_prefix, history)
    for n in range(5):
        first.run('fib', {'order': n}, task_id=f'q{n}', source='CLOUD' if n % 2 else 'CLI')
    first.run('nope', {}, task_id='q-unknown', source='CLI')
    first.process.stop()  # type: ignore[attr-defined]
    # a restart with a lower limit prunes at once
    _launch(launch_task_manager, topic_prefix, history, history_max_results=4)
    client: Client[QueryTaskHistory.Request, QueryTaskHistory.Response] = ros.node.create_client(
        QueryTaskHistory, '/task_manager/query_task_history'
    )
    assert wait_until_ready(client.service_is_ready, TIMEOUT_SEC)

    def ids(**filters: object) -> list[str]:
        request = QueryTaskHistory.Request(**filters)
        tasks = wait_for_future(client.call_async(request), TIMEOUT_SEC, 'history').tasks
        return [t.task_id for t in tasks if t.task_id.startswith('q')]

    newest = ids()
    by_source = ids(source='CLOUD')
    failed = ids(status='ERROR')
    oldest_first = ids(oldest_first=True, limit=2)
    all_rows = wait_for_future(
        client.call_async(QueryTaskHistory.Request(oldest_first=True)), TIMEOUT_SEC, 'history'
    ).tasks
    after = ids(after_sequence=all_rows[1].sequence, oldest_first=True)

    assert newest == ['q-unknown', 'q4', 'q3', 'q2']
    assert set(by_source) <= {'q1', 'q3'} and 'q3' in by_source
    assert failed == ['q-unknown']
    assert [t.sequence for t in all_rows] == sorted(t.sequence for t in all_rows)
    # pruned at start to the 4 newest of the first run
    assert [t.task_id for t in all_rows if t.task_id.startswith('q')] == [
        'q2',
        'q3',
        'q4',
        'q-unknown',
    ]
    assert oldest_first == [t.task_id for t in all_rows[:2] if t.task_id.startswith('q')]
    assert after == [t.task_id for t in all_rows[2:] if t.task_id.startswith('q')]


def test_the_history_keeps_a_large_task_data_as_its_size_and_within_its_bytes(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str, tmp_path: Path
) -> None:
    ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/fib', on_goal=_decide)
    history = tmp_path / 'history.sqlite'
    first = _launch(launch_task_manager, topic_prefix, history)
    # runs (the field Fibonacci has not is left aside), stored with the request's task_data
    large = first.run('fib', {'order': 1, 'pad': 'x' * 900_000}, task_id='large')
    for n in range(5):
        first.run('fib', {'order': n}, task_id=f'b{n}')
    first.process.stop()  # type: ignore[attr-defined]
    stored = sqlite3.connect(history).execute(
        'SELECT task_id, task_data, size FROM tasks ORDER BY sequence'
    )
    rows = {task_id: (task_data, size) for task_id, task_data, size in stored}
    newest_three = sum(rows[f'b{n}'][1] for n in (2, 3, 4))

    # a restart with a byte budget of the three newest rows prunes the others at once
    _launch(launch_task_manager, topic_prefix, history, history_max_bytes=newest_three)
    kept = sqlite3.connect(history).execute('SELECT task_id FROM tasks ORDER BY sequence')

    assert large.task_status == 'DONE'
    assert json.loads(rows['large'][0]) == {'omitted_bytes': 900_023}
    assert rows['large'][1] < 2000
    assert [task_id for (task_id,) in kept] == ['b2', 'b3', 'b4']


def test_a_full_disk_stops_nothing_and_is_logged_once(
    ros: RosHarness, tmp_path: Path, topic_prefix: str
) -> None:
    ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/fib', on_goal=_decide)
    parameters = {
        'tasks': ['fib'],
        'fib': action_task('fib', f'{topic_prefix}/fib', reentrant=True),
        'history_path': str(tmp_path / 'history.sqlite'),
    }
    # files of the node may not grow beyond 256 KiB: the history's log fills up after a few
    # dozen commits, as a full disk would
    node = NodeProcess(
        write_params_file(tmp_path / 'params.yaml', parameters),
        wrapper=['prlimit', f'--fsize={FULL_DISK_BYTES}', '--'],
    )
    probe = TaskManagerProbe(ros)
    try:
        node.wait_for_log('Task Manager ready', TIMEOUT_SEC)
        probe.wait_until_connected()
        outcomes = [probe.run('fib', {'order': 1}, task_id=f'f{n}') for n in range(FULL_DISK_TASKS)]
        probe.wait_result_message(f'f{FULL_DISK_TASKS - 1}')
    finally:
        probe.destroy()
        code = node.stop()

    assert {r.task_status for r in outcomes} == {'DONE'}
    assert len({m.task_id for m in probe.results.snapshot() if m.task_id.startswith('f')}) == (
        FULL_DISK_TASKS
    )
    errors = [line for line in node.log_lines if 'cannot write the task history /' in line]
    assert len(errors) == 1, errors  # once a minute, not once per task
    assert code == 0
