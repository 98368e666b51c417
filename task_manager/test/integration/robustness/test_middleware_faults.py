"""Faults of the DDS middleware under us.

Processes that end without a word (SIGKILL, as a crash or a power loss would end them): the
others forget them within their DDS lease, 5 s (task_manager/fastdds_discovery.xml), not Fast
DDS's 20 s. While a dead participant was remembered, a newcomer now and then never matched
some of the node's endpoints: a taskctl failed with `/task_manager/get_parameters is not
available` in 34 of 240 starts 10-30 s after ten clients were killed, in none of 240 with the
lease (see task_manager/discovery.py).

The middleware watchdog reads Fast DDS's real timer thread, which runs at least at each
announcement (see task_manager/middleware_watchdog.py; its logic: test_middleware_watchdog.py).
"""

import re
import subprocess
import sys
import textwrap
import time

import pytest
from test_msgs.action import Fibonacci

from task_manager.client import TaskManagerClient
from task_manager.middleware_watchdog import timer_threads
from task_manager.testing.gateway import wait_until
from task_manager.testing.harness import RosHarness
from task_manager.testing.process import (
    TASKCTL,
    TASKCTL_REACH_SEC,
    LaunchTaskManager,
    action_task,
    taskctl,
)
from task_manager.testing.servers import ScriptedActionServer

LEASE_SEC = 5.0
# the lease counts from the last message heard, a little before the kill; Fast DDS checks it
# on a timer, and the graph reaches Python through a listener: what a loaded machine may add
FORGOTTEN_WITHIN_SEC = LEASE_SEC + 3.0
TIMEOUT_SEC = 30.0
ANNOUNCEMENT_BOUND_SEC = 3.0  # announcements each 1 s
HELD_TASK_ID = 'held-by-a-dead-client'


def _taskctl_nodes(ros: RosHarness) -> list[str]:
    return [name for name in ros.node.get_node_names() if name.startswith('taskctl_')]


def test_a_killed_taskctl_is_forgotten_within_its_lease_and_the_next_one_served(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/fib')
    probe = launch_task_manager({'fib': action_task('math/fib', f'{topic_prefix}/fib')})
    wait_for_a_minute = ['start', 'system/wait', '{"duration": 60}', '--id', HELD_TASK_ID]
    waiting = subprocess.Popen(
        [TASKCTL, '--timeout', str(TASKCTL_REACH_SEC), *wait_for_a_minute],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        probe.wait_in_progress(HELD_TASK_ID)
        wait_until(lambda: _taskctl_nodes(ros), 'taskctl on the graph', TIMEOUT_SEC)
        waiting.kill()
        killed_at = time.monotonic()
        wait_until(lambda: not _taskctl_nodes(ros), 'the killed taskctl forgotten', TIMEOUT_SEC)
        forgotten_after_sec = time.monotonic() - killed_at
    finally:
        waiting.kill()
        waiting.wait(TIMEOUT_SEC)
    assert forgotten_after_sec < FORGOTTEN_WITHIN_SEC, forgotten_after_sec

    listed = taskctl('tasks')
    assert listed.returncode == 0, listed.stderr
    assert 'math/fib' in listed.stdout


def test_a_killed_node_is_noticed_by_its_clients_within_its_lease(
    launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    probe = launch_task_manager({'fib': action_task('math/fib', f'{topic_prefix}/fib')})
    with TaskManagerClient('vanishing', timeout_sec=TIMEOUT_SEC) as client:
        wait_until(lambda: client.connected, 'the client connected', TIMEOUT_SEC)
        probe.process.kill()
        killed_at = time.monotonic()
        wait_until(lambda: not client.connected, 'the dead node noticed', TIMEOUT_SEC)
        noticed_after_sec = time.monotonic() - killed_at
    assert noticed_after_sec < FORGOTTEN_WITHIN_SEC, noticed_after_sec


@pytest.mark.usefixtures('ros')
def test_fast_dds_timer_thread_is_found_and_runs_at_each_announcement() -> None:
    """This process's participant (the `ros` fixture's), announced each second by the profile."""
    before = timer_threads()
    assert before, 'no thread named dds.ev.* in this process: has Fast DDS renamed it?'
    wait_until(
        lambda: any(timer_threads().get(tid, 0) > count for tid, count in before.items()),
        'the timer thread ran',
        ANNOUNCEMENT_BOUND_SEC,
    )


def test_a_stuck_timer_thread_ends_the_node_with_one_line_and_exit_code_3() -> None:
    """The node's wiring (node_process), in a fresh interpreter: a stand-in timer thread that
    never runs."""
    script = textwrap.dedent(
        """
        import functools, time
        from task_manager import middleware_watchdog
        from task_manager.ros import node_process

        node_process.MiddlewareWatchdog = functools.partial(
            middleware_watchdog.MiddlewareWatchdog, read=lambda: {42: 1}
        )
        node_process._watch_the_middleware(0.3)
        time.sleep(30)
        """
    )
    ended = subprocess.run(
        [sys.executable, '-c', script], capture_output=True, text=True, timeout=TIMEOUT_SEC
    )
    assert ended.returncode == 3, ended.stderr
    [line] = ended.stderr.splitlines()
    assert '[FATAL]' in line and '[task_manager]: the DDS middleware is stuck' in line
    stalled = re.search(r'has not run for ([0-9.]+) s', line)
    assert stalled is not None and float(stalled.group(1)) >= 0.3
