"""Server loss, bounded waits and clean shutdown: every request answered, nothing stuck."""

import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from typing import Any

import psutil
import pytest
import rclpy
from action_msgs.msg import GoalStatus
from rclpy.action.server import ActionServer, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import SingleThreadedExecutor
from rclpy.task import Future
from std_srvs.srv import SetBool
from test_msgs.action import Fibonacci

from task_manager.rclpy_tools.spin_thread import SpinThread
from task_manager.testing.harness import RosHarness, WaitTimeoutError, wait_for_future
from task_manager.testing.process import LaunchTaskManager, action_task, service_task
from task_manager.testing.servers import ScriptedActionServer, ScriptedGoal, ScriptedService
from task_manager.testing.stuck_servers import READY_LINE, SHORT_LEASE_PROFILE

TIMEOUT_SEC = 15.0
WATCH = {'server_check_period': 0.2, 'server_loss_timeout': 1.0}
# more goals than an action server's result service keeps unread requests (10 by default)
GOALS_IN_FLIGHT = 30
# goals running 20 ticks of a 0.1 s server watch, many times more than the node asks for
# results at a time (8)
LONG_GOALS = 60
LONG_GOAL_SEC = 2.0
# goals at a server slow to accept each: all are sent only after twice goal_response_timeout
SLOW_GOALS = 200
SLOW_ACCEPTANCE_SEC = 0.01
HOLD_ORDER = 100  # goals of this order or more wait for the test's release
# how long a server stays busy once a burst of requests has reached it: longer than the node
# once waited before it sent more (0.5 s), so that the burst alone fills the server's queue
SERVER_BUSY_SEC = 2.0
# short enough that a held task outlives several, long enough that the test's own pace
# between two tasks (a process stalled 0.7 s under four test workers on two cores) is not silence
LOSS_TIMEOUT_SEC = 1.5


@pytest.fixture
def stuck_servers(topic_prefix: str) -> Iterator[subprocess.Popen[str]]:
    """A real server process (short DDS lease), killed by the tests."""
    env = dict(os.environ, FASTDDS_DEFAULT_PROFILES_FILE=str(SHORT_LEASE_PROFILE))
    process = subprocess.Popen(
        [
            sys.executable,
            '-m',
            'task_manager.testing.stuck_servers',
            f'{topic_prefix}/stuck_action',
            f'{topic_prefix}/stuck_service',
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=env,
    )
    assert process.stdout is not None
    # ready once it says so (Fast DDS may print an error line before: a shared memory port
    # another process holds)
    assert any(line.strip() == READY_LINE for line in process.stdout), 'never ready'
    yield process
    if process.poll() is None:
        process.kill()
    process.wait(TIMEOUT_SEC)


def _tasks(prefix: str) -> dict[str, dict[str, object]]:
    return {
        'act': action_task('stuck_action', f'{prefix}/stuck_action'),
        'srv': service_task('stuck_service', f'{prefix}/stuck_service'),
    }


def test_tasks_end_error_when_their_server_process_dies(
    ros: RosHarness,
    launch_task_manager: LaunchTaskManager,
    topic_prefix: str,
    stuck_servers: subprocess.Popen[str],
) -> None:
    tm = launch_task_manager(_tasks(topic_prefix), server_wait_timeout=5.0, **WATCH)
    action = tm.send('stuck_action', {'order': 1}, task_id='on-action')
    service = tm.send('stuck_service', {'data': True}, task_id='on-service')
    tm.wait_active(lambda tasks: {'on-action', 'on-service'} <= {t for t, _ in tasks})

    stuck_servers.kill()
    killed = time.monotonic()
    action_result = tm.result_of(action).result
    action_after_sec = time.monotonic() - killed
    service_result = tm.result_of(service).result

    assert action_result.task_status == 'ERROR'
    assert 'stopped answering' in json.loads(action_result.task_result)['error']
    assert action_after_sec < 5.0  # loss timeout 1 s + check period 0.2 s + margin
    assert service_result.task_status == 'ERROR'
    assert 'left the ROS graph' in json.loads(service_result.task_result)['error']
    tm.wait_active(lambda tasks: tasks == [], 'no active task left')
    assert [m.task_status for m in tm.results_for('on-action')] == ['ERROR']
    assert [m.task_status for m in tm.results_for('on-service')] == ['ERROR']


def test_a_service_that_never_responds_is_bounded(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    service = ScriptedService(ros.node, SetBool, f'{topic_prefix}/set')
    tm = launch_task_manager(
        {'set': service_task('set', f'{topic_prefix}/set')}, service_response_timeout=0.5
    )

    result = tm.run('set', {'data': True})

    assert result.task_status == 'ERROR'
    assert 'no response within 0.5 s' in json.loads(result.task_result)['error']
    service.wait_for_calls(1, TIMEOUT_SEC)[0].respond(success=True)  # late: ignored
    assert tm.run('nope', {}).error_code == 'unknown_task'  # the node still serves


def test_sigint_cancels_running_tasks_publishes_results_and_exits_0(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    drive = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/drive')
    ScriptedService(ros.node, SetBool, f'{topic_prefix}/set')
    tm = launch_task_manager(
        {
            'drive': action_task('drive', f'{topic_prefix}/drive'),
            'set': service_task('set', f'{topic_prefix}/set', cancel_timeout=0.5),
        }
    )
    driving = tm.send('drive', {'order': 1}, task_id='driving')
    driving_result = driving.get_result_async()  # asked at once, as real clients do
    tm.send('set', {'data': True}, task_id='setting')
    tm.wait_active(lambda tasks: {'driving', 'setting'} <= {t for t, _ in tasks})
    process = tm.process
    pid = process.process.pid
    threads = psutil.Process(pid).num_threads()

    process.process.send_signal(signal.SIGINT)
    exit_code = process.wait_exit(TIMEOUT_SEC)

    assert exit_code == 0
    assert drive.wait_for_goals(1, TIMEOUT_SEC)[0].cancel_requested.is_set()
    assert tm.wait_result_message('driving').task_status == 'CANCELED'
    setting = tm.wait_result_message('setting')
    assert setting.task_status == 'ERROR'
    assert 'shutting down' in json.loads(setting.task_result)['error']
    assert wait_for_future(driving_result, TIMEOUT_SEC, 'result').status == (
        GoalStatus.STATUS_ABORTED
    )
    assert threads < 40
    with pytest.raises(WaitTimeoutError):
        process.wait_for_log(r'Traceback', 0.1)


@pytest.fixture
def busy_server_node(ros_context: None) -> Iterator[rclpy.node.Node]:
    """A node spun by an executor of its own, which a test can keep busy."""
    node = rclpy.create_node(f'busy_server_{os.getpid()}')
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    spinner = SpinThread(executor, node, 'busy-server')
    spinner.start()
    yield node
    assert spinner.stop(TIMEOUT_SEC), 'the busy server is still in a callback'
    executor.shutdown()
    node.destroy_node()


def test_every_result_comes_back_when_a_busy_server_drops_the_requests_for_them(
    ros: RosHarness,
    launch_task_manager: LaunchTaskManager,
    topic_prefix: str,
    busy_server_node: rclpy.node.Node,
) -> None:
    """A server on rclpy's default QoS keeps only the last 10 unread GetResult requests: those
    sent while it is busy are dropped, and the goals' results must be asked for again."""
    tm = launch_task_manager(
        {'drive': action_task('drive', f'{topic_prefix}/drive', reentrant=True)},
        server_check_period=0.2,
        server_loss_timeout=30.0,
    )
    release = threading.Event()

    def keep_busy_after_the_last(goal: ScriptedGoal) -> None:
        if len(server.goals.items) == GOALS_IN_FLIGHT:
            release.wait(TIMEOUT_SEC)  # the server's executor does nothing else meanwhile

    server = ScriptedActionServer(
        busy_server_node, Fibonacci, f'{topic_prefix}/drive', on_goal=keep_busy_after_the_last
    )
    ids = [f'drive-{index}' for index in range(GOALS_IN_FLIGHT)]
    handles = [tm.send('drive', {'order': 1}, task_id=task_id) for task_id in ids]
    # every goal accepted, so the Task Manager has asked for every result
    tm.wait_active(
        lambda tasks: sum(status == 'IN_PROGRESS' for _, status in tasks) == GOALS_IN_FLIGHT
    )
    threading.Timer(0.5, release.set).start()  # the server stays busy half a second more
    for goal in server.wait_for_goals(GOALS_IN_FLIGHT, TIMEOUT_SEC):
        goal.succeed()

    statuses = [tm.result_of(handle).result.task_status for handle in handles]

    assert statuses == ['DONE'] * GOALS_IN_FLIGHT
    tm.wait_active(lambda tasks: tasks == [], 'no active task left')
    assert [len(tm.results_for(task_id)) for task_id in ids] == [1] * GOALS_IN_FLIGHT


def test_every_result_comes_back_from_a_server_that_keeps_none_once_its_goal_ended(
    launch_task_manager: LaunchTaskManager,
    topic_prefix: str,
    busy_server_node: rclpy.node.Node,
) -> None:
    """A server holds each GetResult request until its goal ends and answers them then; one
    that keeps no result afterwards (result_timeout 0) answers "unknown goal" to any asked
    later. Goals running through many of the node's watch ticks (each may ask again, paced 8
    at a time) must still end DONE: the first request is awaited until the task ends."""
    tm = launch_task_manager(
        {'drive': action_task('drive', f'{topic_prefix}/drive', reentrant=True)},
        server_check_period=0.1,
        server_loss_timeout=30.0,
    )
    server = ScriptedActionServer(
        busy_server_node, Fibonacci, f'{topic_prefix}/drive', result_timeout=0
    )
    ids = [f'drive-{index}' for index in range(LONG_GOALS)]
    handles = [tm.send('drive', {'order': 1}, task_id=task_id) for task_id in ids]
    goals = server.wait_for_goals(LONG_GOALS, TIMEOUT_SEC)
    tm.wait_active(lambda tasks: sum(status == 'IN_PROGRESS' for _, status in tasks) == len(ids))

    def end_all() -> None:
        for goal in goals:
            goal.succeed()

    threading.Timer(LONG_GOAL_SEC, end_all).start()  # the goals run that long more

    statuses = [tm.result_of(handle).result.task_status for handle in handles]

    assert statuses == ['DONE'] * LONG_GOALS


def test_a_goal_its_restarted_server_no_longer_knows_ends_error(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm = launch_task_manager(
        {'drive': action_task('drive', f'{topic_prefix}/drive')},
        server_check_period=0.2,
        server_loss_timeout=30.0,
    )
    first = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/drive')
    drive = tm.send('drive', {'order': 1}, task_id='forgotten')
    first.wait_for_goals(1, TIMEOUT_SEC)
    ros.on_executor(first.destroy)
    ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/drive')  # knows no goal

    result = tm.result_of(drive).result

    assert result.task_status == 'ERROR'
    assert 'no longer knows the goal' in json.loads(result.task_result)['error']


def test_a_stop_cancels_every_goal_of_a_server_that_keeps_only_ten_requests(
    ros: RosHarness,
    launch_task_manager: LaunchTaskManager,
    topic_prefix: str,
    busy_server_node: rclpy.node.Node,
) -> None:
    """system/stop sends a cancel per goal; a server on rclpy's default QoS keeps only its
    last 10 unread requests, so a burst of them reached it as 19 of 200. They go out at most
    8 unanswered at a time."""
    tm = launch_task_manager(
        {
            'drive': action_task(
                'drive', f'{topic_prefix}/drive', reentrant=True, cancel_on_stop=True
            )
        },
        server_check_period=0.2,
        server_loss_timeout=30.0,
    )
    release = threading.Event()
    server = ScriptedActionServer(busy_server_node, Fibonacci, f'{topic_prefix}/drive')
    ids = [f'drive-{index}' for index in range(GOALS_IN_FLIGHT * 2)]
    handles = [tm.send('drive', {'order': 1}, task_id=task_id) for task_id in ids]
    tm.wait_active(lambda tasks: sum(status == 'IN_PROGRESS' for _, status in tasks) == len(ids))
    server.wait_for_goals(len(ids), TIMEOUT_SEC)

    # the server's executor is busy for a moment as the stop's cancels arrive
    def keep_busy() -> None:
        release.wait(TIMEOUT_SEC)

    busy_server_node.create_guard_condition(keep_busy).trigger()
    stop = tm.send('system/stop', {})
    threading.Timer(SERVER_BUSY_SEC, release.set).start()

    stopped = tm.result_of(stop).result

    assert stopped.task_status == 'DONE', stopped.task_result
    assert all(goal.cancel_requested.is_set() for goal in server.goals.items)
    assert [tm.result_of(h).result.task_status for h in handles] == ['CANCELED'] * len(ids)


def test_a_burst_of_service_calls_reaches_a_server_that_keeps_only_ten_requests(
    launch_task_manager: LaunchTaskManager,
    topic_prefix: str,
    busy_server_node: rclpy.node.Node,
) -> None:
    """A service server on rclpy's default QoS keeps its last 10 unread requests: 30 calls
    sent at once while its executor is busy lost 20, each task then waiting for its response
    until service_response_timeout. They go out at most 8 unanswered at a time, and no more
    while the server answers none, however long it stays busy (after 0.5 s, 4 were lost
    still)."""
    release = threading.Event()
    server = ScriptedService(
        busy_server_node,
        SetBool,
        f'{topic_prefix}/lights',
        on_call=lambda call: call.respond(success=True),
    )
    tm = launch_task_manager(
        {'lights': service_task('lights', f'{topic_prefix}/lights', reentrant=True)},
        service_response_timeout=TIMEOUT_SEC / 2,
    )
    tm.run('lights', {'data': True}, task_id='warm-up')  # the node has found the server

    def keep_busy() -> None:  # the server's executor takes no request meanwhile
        release.wait(TIMEOUT_SEC)

    busy_server_node.create_guard_condition(keep_busy).trigger()
    handles = [
        tm.send('lights', {'data': True}, task_id=f'call-{n}') for n in range(GOALS_IN_FLIGHT)
    ]
    tm.wait_active(
        lambda tasks: sum(status == 'IN_PROGRESS' for _, status in tasks) == GOALS_IN_FLIGHT
    )
    threading.Timer(SERVER_BUSY_SEC, release.set).start()

    results = [tm.result_of(handle).result for handle in handles]

    assert [r.task_status for r in results] == ['DONE'] * GOALS_IN_FLIGHT, [
        r.task_result for r in results if r.task_status != 'DONE'
    ]
    assert len(server.calls.items) == GOALS_IN_FLIGHT + 1


def test_goals_waiting_their_turn_in_the_node_are_not_timed_out_as_the_servers_delay(
    launch_task_manager: LaunchTaskManager,
    topic_prefix: str,
    busy_server_node: rclpy.node.Node,
) -> None:
    """goal_response_timeout is the time an action server takes to answer a goal. A burst
    waits its turn in the node (8 goals unanswered at a time): 200 goals at a server taking
    10 ms over each are all sent within 2 s, twice the timeout, and each is answered in
    80 ms at most once sent; none may fail as if the server had not answered."""

    def slow_acceptance(_goal: Any) -> GoalResponse:
        time.sleep(SLOW_ACCEPTANCE_SEC)  # the server's own slowness, not a wait of the test
        return GoalResponse.ACCEPT

    def succeed(goal_handle: Any) -> Fibonacci.Result:
        goal_handle.succeed()
        return Fibonacci.Result()

    server = ActionServer(
        busy_server_node,
        Fibonacci,
        f'{topic_prefix}/drive',
        execute_callback=succeed,
        goal_callback=slow_acceptance,
    )
    tm = launch_task_manager(
        {'drive': action_task('drive', f'{topic_prefix}/drive', reentrant=True)},
        goal_response_timeout=1.0,
    )
    handles = [tm.send('drive', {'order': 1}, task_id=f'queued-{n}') for n in range(SLOW_GOALS)]

    statuses = [tm.result_of(handle).result.task_status for handle in handles]

    assert statuses == ['DONE'] * SLOW_GOALS
    server.destroy()


class NoCancelAnswers(ActionServer[Any, Any, Any]):
    """A live action server whose cancel service takes every request and answers none: the
    node's probe (a cancel of a goal that does not exist) stays unanswered, as one does whose
    answer is lost or waits behind a burst."""

    async def _execute_cancel_request(self, _request_header_and_message: Any) -> None:
        return None


def test_a_server_that_answers_no_probe_but_ends_goals_is_not_lost(
    launch_task_manager: LaunchTaskManager,
    topic_prefix: str,
    busy_server_node: rclpy.node.Node,
) -> None:
    """A goal's response and a result are signs of life as much as the probe's answer: a task
    held for three loss timeouts ends DONE while others end one after another (before, the
    unanswered probe alone counted, and every task of the server ended ERROR as lost)."""
    release: Future[None] = Future()

    async def execute(goal_handle: Any) -> Fibonacci.Result:
        if goal_handle.request.order >= HOLD_ORDER:
            await release
        goal_handle.succeed()
        return Fibonacci.Result()

    server = NoCancelAnswers(
        busy_server_node,
        Fibonacci,
        f'{topic_prefix}/drive',
        execute_callback=execute,
        callback_group=ReentrantCallbackGroup(),
    )
    tm = launch_task_manager(
        {'drive': action_task('drive', f'{topic_prefix}/drive', reentrant=True)},
        server_check_period=0.1,
        server_loss_timeout=LOSS_TIMEOUT_SEC,
    )
    held = tm.send('drive', {'order': HOLD_ORDER}, task_id='held')
    tm.wait_in_progress('held')
    others = 0
    until = time.monotonic() + 3 * LOSS_TIMEOUT_SEC  # the scenario's length, not a wait
    while time.monotonic() < until:
        assert tm.run('drive', {'order': 1}, task_id=f'other-{others}').task_status == 'DONE'
        others += 1
    assert busy_server_node.executor is not None
    busy_server_node.executor.create_task(lambda: release.set_result(None))

    assert tm.result_of(held).result.task_status == 'DONE'
    server.destroy()
