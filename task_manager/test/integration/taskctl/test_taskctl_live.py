"""taskctl's live views through a pseudo-terminal (pexpect), and their absence in a pipe; a
follow held up past the DDS lease that no longer hears the node."""

import json
import os
import re
import signal
import subprocess
import time
from typing import Any

import pexpect
from task_manager_msgs.msg import TaskEvent
from test_msgs.action import Fibonacci

from task_manager.client.hearing import ANSWER_SEC, HELD_UP_SEC
from task_manager.core.names import TASK_EVENTS_TOPIC
from task_manager.rclpy_tools import qos
from task_manager.testing.harness import RosHarness, WaitTimeoutError
from task_manager.testing.process import (
    ABORT_TIMEOUT_SEC,
    TASKCTL,
    LaunchTaskManager,
    action_task,
    without_shared_memory_lines,
)
from task_manager.testing.servers import ScriptedActionServer, publish_feedback_until

TIMEOUT_SEC = 30.0
TERMINAL_ROWS, TERMINAL_COLUMNS = 24, 160
# The live line: status, elapsed time (group 1), latest feedback
LIVE_LINE = r'IN_PROGRESS  (\d+\.\d) s  \{"sequence": \[1, 2, 3\]\}'
# What terminals get besides text: colours, cursor moves, line erasing
ANSI_CONTROL = re.compile(r'\x1b\[[0-9;?]*[A-Za-z]|\r')
RESULT_KEYS = ['task_id', 'task_name', 'status', 'error_code', 'result', 'source']


def _elapsed_shown(terminal: 'pexpect.spawn[str]') -> str:
    """The elapsed time in the live line just matched."""
    assert isinstance(terminal.match, re.Match)
    return terminal.match.group(1)


def _launch(ros: RosHarness, launch: LaunchTaskManager, prefix: str) -> ScriptedActionServer:
    server = ScriptedActionServer(ros.node, Fibonacci, f'{prefix}/fib')
    launch({'fib': action_task('math/fib', f'{prefix}/fib', reentrant=True)})
    return server


def _expected_result(task_id: str) -> dict[str, Any]:
    return {
        'task_id': task_id,
        'task_name': 'math/fib',
        'status': 'DONE',
        'error_code': '',
        'result': {'sequence': [8]},
        'source': 'CLI',
    }


def test_start_on_a_terminal_shows_feedback_and_elapsed_time_live(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    server = _launch(ros, launch_task_manager, topic_prefix)
    terminal = pexpect.spawn(
        TASKCTL,
        ['start', 'math/fib', '{"order": 6}', '--id', 'live-1'],
        env=dict(os.environ, TERM='xterm-256color'),
        dimensions=(TERMINAL_ROWS, TERMINAL_COLUMNS),
        encoding='utf-8',
        timeout=TIMEOUT_SEC,
    )
    try:
        goal = server.wait_for_goals(1, TIMEOUT_SEC)[0]

        def shown(wait_sec: float) -> bool:
            return terminal.expect([LIVE_LINE, pexpect.TIMEOUT], timeout=wait_sec) == 0

        publish_feedback_until(goal, Fibonacci.Feedback(sequence=[1, 2, 3]), shown, TIMEOUT_SEC)
        elapsed = {_elapsed_shown(terminal)}
        deadline = time.monotonic() + TIMEOUT_SEC
        while len(elapsed) < 2 and time.monotonic() < deadline:  # the time goes on
            terminal.expect(LIVE_LINE)
            elapsed.add(_elapsed_shown(terminal))
        goal.succeed(Fibonacci.Result(sequence=[8]))
        terminal.expect(pexpect.EOF)
        assert terminal.before is not None
        after_live = ANSI_CONTROL.sub('', terminal.before)
    finally:
        terminal.close(force=True)

    assert len(elapsed) >= 2, elapsed
    assert terminal.exitstatus == 0
    start = after_live.rindex('{', 0, after_live.index('"task_id"'))  # past the live frames
    printed, _ = json.JSONDecoder().raw_decode(after_live[start:])
    assert printed == _expected_result('live-1')


def test_start_in_a_pipe_prints_the_result_json_only(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    server = _launch(ros, launch_task_manager, topic_prefix)
    events = ros.record(TaskEvent, TASK_EVENTS_TOPIC, qos.TASK_EVENTS)
    events.wait_matched(TIMEOUT_SEC)
    piped = subprocess.Popen(
        [TASKCTL, 'start', 'math/fib', '{"order": 6}', '--id', 'piped-1'],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        goal = server.wait_for_goals(1, TIMEOUT_SEC)[0]

        def forwarded(wait_sec: float) -> bool:
            try:
                events.wait_until(
                    lambda msgs: any(m.event == TaskEvent.FEEDBACK for m in msgs), wait_sec
                )
            except WaitTimeoutError:
                return False
            return True

        publish_feedback_until(goal, Fibonacci.Feedback(sequence=[1, 2, 3]), forwarded, TIMEOUT_SEC)
        goal.succeed(Fibonacci.Result(sequence=[8]))
        stdout, stderr = piped.communicate(timeout=TIMEOUT_SEC)
    finally:
        if piped.poll() is None:
            piped.kill()
            piped.communicate()

    assert piped.returncode == 0
    assert without_shared_memory_lines(stderr) == ''
    printed = json.loads(stdout)
    assert printed == _expected_result('piped-1')
    assert list(printed) == RESULT_KEYS  # as before the live view
    assert stdout == json.dumps(printed, indent=2) + '\n'


def test_a_follow_held_up_that_no_longer_hears_the_node_says_so_and_exits_4(
    launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    """taskctl stopped (SIGSTOP, as Ctrl-Z) with the node past its check's hold-up, then let
    go while the node stays stopped: it hears nothing, says so and ends (not a silent wait)."""
    tm = launch_task_manager({'fib': action_task('math/fib', f'{topic_prefix}/fib')})
    tm.run('system/wait', {'duration': 0.001}, task_id='kept')
    node = tm.process.process.pid
    following = subprocess.Popen(
        [TASKCTL, 'results', '--follow', '--json'],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    assert following.stdout is not None
    try:
        # it follows once the kept result is shown (Fast DDS may print a line before)
        assert any('"kept"' in line for line in following.stdout), 'no kept result shown'
        os.kill(node, signal.SIGSTOP)
        os.kill(following.pid, signal.SIGSTOP)
        time.sleep(HELD_UP_SEC + 1.5)  # the hold-up is this test's input, not a wait
        os.kill(following.pid, signal.SIGCONT)
        code = following.wait(ANSWER_SEC + TIMEOUT_SEC)
    finally:
        os.kill(node, signal.SIGCONT)
        if following.poll() is None:  # its threads' stacks (faulthandler), then its output
            following.send_signal(signal.SIGABRT)
            try:
                following.wait(ABORT_TIMEOUT_SEC)
            except subprocess.TimeoutExpired:
                following.kill()
                following.wait()
            print('taskctl did not end; what it printed:\n' + following.stdout.read())

    assert code == 4
    assert 'no longer hears the Task Manager' in following.stdout.read()
