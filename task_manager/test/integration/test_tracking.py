"""/task_manager/active_tasks and /task_manager/results (BEHAVIOUR.md, What everyone can see)."""

from rclpy.client import Client
from task_manager_msgs.msg import ActiveTaskArray
from task_manager_msgs.srv import GetTaskResults
from test_msgs.action import Fibonacci

from task_manager.ros import qos
from task_manager.testing.harness import RosHarness, wait_for_future
from task_manager.testing.process import LaunchTaskManager, action_task
from task_manager.testing.servers import ScriptedActionServer

TIMEOUT_SEC = 15.0


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
    assert client.wait_for_service(timeout_sec=TIMEOUT_SEC)

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
