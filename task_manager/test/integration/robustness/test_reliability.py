"""Server loss, bounded waits and clean shutdown: every request answered, nothing stuck."""

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator

import psutil
import pytest
from action_msgs.msg import GoalStatus
from std_srvs.srv import SetBool
from test_msgs.action import Fibonacci

from task_manager.testing.harness import RosHarness, WaitTimeoutError, wait_for_future
from task_manager.testing.process import LaunchTaskManager, action_task, service_task
from task_manager.testing.servers import ScriptedActionServer, ScriptedService
from task_manager.testing.stuck_servers import READY_LINE, SHORT_LEASE_PROFILE

TIMEOUT_SEC = 15.0
WATCH = {'server_check_period': 0.2, 'server_loss_timeout': 1.0}


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
    assert process.stdout.readline().strip() == READY_LINE
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
