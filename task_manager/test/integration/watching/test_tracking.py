"""/task_manager/active_tasks and /task_manager/results (BEHAVIOUR.md, What everyone can see)."""

import time

from rclpy.client import Client
from task_manager_msgs.msg import ActiveTaskArray
from task_manager_msgs.srv import GetTaskResults
from test_msgs.action import Fibonacci

from task_manager.rclpy_tools import qos
from task_manager.rclpy_tools.server_wait import wait_until_ready
from task_manager.ros.recording.active_tasks import LARGE_LIST, LARGE_LIST_RATE_HZ
from task_manager.testing.harness import RosHarness, wait_for_future
from task_manager.testing.process import LaunchTaskManager, action_task
from task_manager.testing.servers import ScriptedActionServer, ScriptedGoal

TIMEOUT_SEC = 15.0
HOLD = 50  # Fibonacci orders at or above it are held by the server


def _ids(message: ActiveTaskArray) -> list[tuple[str, str]]:
    return [(t.task_id, t.task_status) for t in message.active_tasks]


def test_active_tasks_show_progress_then_final_status_then_removal(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    server = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/fib')
    tm = launch_task_manager({'fib': action_task('fib', f'{topic_prefix}/fib', reentrant=True)})
    handle = tm.send('fib', {'order': 1}, task_id='tracked', source='Voice control')
    tm.wait_in_progress('tracked')
    entry = next(t for m in tm.active.snapshot() for t in m.active_tasks if t.task_id == 'tracked')
    assert (entry.task_name, entry.source) == ('fib', 'Voice control')

    server.wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    tm.result_of(handle)

    def after_progress(messages: list[ActiveTaskArray]) -> list[list[tuple[str, str]]]:
        states = [_ids(m) for m in messages]
        return states[states.index([('tracked', 'IN_PROGRESS')]) + 1 :]

    later = tm.active.wait_until(
        lambda msgs: [] in after_progress(msgs) and after_progress(msgs), TIMEOUT_SEC
    )
    assert later == [[('tracked', 'DONE')], []]


def test_late_subscriber_gets_the_current_active_list(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    server = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/fib')
    tm = launch_task_manager({'fib': action_task('fib', f'{topic_prefix}/fib')})
    handle = tm.send('fib', {'order': 1}, task_id='long')
    tm.wait_in_progress('long')

    late = ros.record(ActiveTaskArray, '/task_manager/active_tasks', qos.ACTIVE_TASKS)

    late.wait_until(lambda msgs: msgs and _ids(msgs[-1]) == [('long', 'IN_PROGRESS')], TIMEOUT_SEC)
    server.wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    tm.result_of(handle)


def test_exactly_one_result_per_request_including_failed_ones(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    ScriptedActionServer(
        ros.node,
        Fibonacci,
        f'{topic_prefix}/fib',
        on_goal=lambda goal: goal.succeed() if goal.request.order < 100 else None,
    )
    tm = launch_task_manager({'fib': action_task('fib', f'{topic_prefix}/fib', reentrant=True)})
    held = tm.send('fib', {'order': 100}, task_id='held')
    tm.wait_in_progress('held')
    requests = {
        'ok': ('fib', '{"order": 1}'),
        'unknown': ('nope', '{}'),
        'bad-json': ('fib', '{'),
        'held': ('fib', '{"order": 2}'),  # duplicate of the active 'held'
    }
    for task_id, (name, data) in requests.items():
        tm.run(name, data, task_id=task_id)
    tm.cancel(held)
    tm.result_of(held)
    tm.run('fib', {'order': 1}, task_id='sentinel')
    tm.wait_result_message('sentinel')  # results arrive in order: everything before is in

    counts = {task_id: len(tm.results_for(task_id)) for task_id in [*requests, 'sentinel']}
    assert counts == {'ok': 1, 'unknown': 1, 'bad-json': 1, 'held': 2, 'sentinel': 1}
    assert [m.error_code for m in tm.results_for('held')] == ['duplicate_id', '']


def test_kept_results_can_be_fetched_after_the_fact(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/fib', on_goal=lambda g: g.succeed())
    tm = launch_task_manager(
        {'fib': action_task('fib', f'{topic_prefix}/fib')}, results_history_size=3
    )
    for task_id in ('r1', 'r2', 'r3', 'r4'):
        tm.run('fib', {'order': 1}, task_id=task_id)
    tm.run('nope', {}, task_id='r5')
    client: Client[GetTaskResults.Request, GetTaskResults.Response] = ros.node.create_client(
        GetTaskResults, '/task_manager/get_task_results'
    )
    assert wait_until_ready(client.service_is_ready, TIMEOUT_SEC)

    everything = wait_for_future(
        client.call_async(GetTaskResults.Request(max_results=0)), TIMEOUT_SEC, 'results'
    )
    newest = wait_for_future(
        client.call_async(GetTaskResults.Request(max_results=2)), TIMEOUT_SEC, 'results'
    )

    assert [(r.task_id, r.task_status) for r in everything.results] == [
        ('r3', 'DONE'),
        ('r4', 'DONE'),
        ('r5', 'ERROR'),
    ]
    assert [r.task_id for r in newest.results] == ['r4', 'r5']
    ros.node.destroy_client(client)


LARGE = LARGE_LIST + 10
QUICK_TASKS = 40


def test_a_large_list_goes_out_at_a_bounded_rate_and_shows_every_end_once(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    def decide(goal: ScriptedGoal) -> None:
        if goal.request.order < HOLD:
            goal.succeed(Fibonacci.Result())

    server = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/fib', on_goal=decide)
    tm = launch_task_manager({'fib': action_task('fib', f'{topic_prefix}/fib', reentrant=True)})
    for n in range(LARGE):
        tm.send('fib', {'order': HOLD}, task_id=f'held-{n}')
    tm.wait_active(lambda tasks: len(tasks) == LARGE, f'{LARGE} tasks active')
    before = len(tm.active.snapshot())

    began = time.monotonic()
    for n in range(QUICK_TASKS):
        tm.run('fib', {'order': 1}, task_id=f'quick-{n}')
    elapsed_sec = time.monotonic() - began
    last = f'quick-{QUICK_TASKS - 1}'

    def after_the_last_end(messages: list[ActiveTaskArray]) -> list[list[tuple[str, str]]] | None:
        lists = [_ids(m) for m in messages[before:]]
        shown = [i for i, tasks in enumerate(lists) if (last, 'DONE') in tasks]
        return lists if shown and len(lists) > shown[-1] + 1 else None

    lists = tm.active.wait_until(after_the_last_end, TIMEOUT_SEC, f'{last} shown ended, then gone')
    for goal in server.goals.items:
        goal.succeed(Fibonacci.Result())

    # each publication is one list, or two when tasks ended (with their end, then without)
    assert len(lists) <= 2 * (LARGE_LIST_RATE_HZ * elapsed_sec + 2)
    for n in range(QUICK_TASKS):
        shown = [i for i, tasks in enumerate(lists) if (f'quick-{n}', 'DONE') in tasks]
        assert len(shown) == 1, f'quick-{n} shown DONE in {len(shown)} lists'
        assert all(f'quick-{n}' not in dict(tasks) for tasks in lists[shown[0] + 1 :])
    assert all(len(tasks) >= LARGE for tasks in lists)
