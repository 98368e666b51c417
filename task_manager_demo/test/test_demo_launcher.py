"""`task-manager-demo`: stops both children on a signal, leaves none behind when killed,
fails loudly when a child dies early, and starts again a child that asks for it (exit 3)."""

import re
import signal
import sys
import time
from pathlib import Path

import httpx
import psutil
import pytest

from task_manager.client.hearing import ANSWER_SEC, HELD_UP_SEC
from task_manager.testing.gateway import wait_until
from task_manager.testing.process import write_params_file
from task_manager_demo.testing import DemoProcess

START_TIMEOUT_SEC = 30.0
STOP_TIMEOUT_SEC = 30.0
# any free port for the dashboard: the tests may run beside a `make run`
LAUNCHER = [str(Path(sys.executable).with_name('task-manager-demo')), '--web-port', '0']

pytestmark = pytest.mark.ros


def alive(processes: list[psutil.Process]) -> list[psutil.Process]:
    return [p for p in processes if p.is_running() and p.status() != psutil.STATUS_ZOMBIE]


def test_sigterm_stops_the_robot_and_the_task_manager_and_exits_0(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv('RCUTILS_COLORIZED_OUTPUT', '1')  # as on a terminal
    demo = DemoProcess('task-manager-demo', LAUNCHER)
    try:
        demo.wait_for_line(r'^Ctrl-C stops', START_TIMEOUT_SEC)
        assert '  tasks:  navigation/navigate_to_pose, navigation/spin,' in demo.output
        children = psutil.Process(demo.pid).children()
        assert len(children) == 3  # the robot, the Task Manager, the web gateway

        demo.child.process.send_signal(signal.SIGTERM)

        assert demo.wait_exit(STOP_TIMEOUT_SEC) == 0, demo.output
    finally:
        if demo.child.exit_code is None:
            demo.stop()
    assert alive(children) == []


def test_sighup_stops_everything_as_ctrl_c_does() -> None:
    demo = DemoProcess('task-manager-demo', LAUNCHER)
    try:
        demo.wait_for_line(r'^Ctrl-C stops', START_TIMEOUT_SEC)
        children = psutil.Process(demo.pid).children()

        demo.child.process.send_signal(signal.SIGHUP)  # the terminal window was closed

        assert demo.wait_exit(STOP_TIMEOUT_SEC) == 0, demo.output
    finally:
        if demo.child.exit_code is None:
            demo.stop()
    assert 'the robot and the Task Manager have stopped' in demo.output
    assert alive(children) == []


def test_a_killed_launcher_leaves_no_child_behind() -> None:
    demo = DemoProcess('task-manager-demo', LAUNCHER)
    try:
        demo.wait_for_line(r'^Ctrl-C stops', START_TIMEOUT_SEC)
        children = psutil.Process(demo.pid).children()
        assert len(children) == 3  # the robot, the Task Manager, the web gateway

        demo.child.process.kill()  # SIGKILL: the launcher cannot stop its children itself

        _, still_running = psutil.wait_procs(children, timeout=STOP_TIMEOUT_SEC)
    finally:
        if demo.child.exit_code is None:
            demo.stop()
    for orphan in still_running:
        orphan.kill()
    assert still_running == []
    assert demo.wait_exit(STOP_TIMEOUT_SEC) == -signal.SIGKILL


def test_a_child_that_dies_before_it_is_ready_fails_the_demo_with_its_output(
    tmp_path: Path,
) -> None:
    unknown_interface = {'task_name': 'x/oops', 'topic': '/oops', 'msg_interface': 'no/srv/X'}
    params = write_params_file(
        tmp_path / 'bad.yaml', {'tasks': ['oops'], 'oops': unknown_interface}
    )
    demo = DemoProcess('task-manager-demo', [*LAUNCHER, '--params-file', str(params)])

    code = demo.wait_exit(STOP_TIMEOUT_SEC)

    assert code == 1, demo.output
    assert 'task_manager exited with code 2 before it was ready' in demo.output
    assert 'x/oops' in demo.output
    assert 'Task Manager ready' not in demo.output
    assert 'killing' not in demo.output, demo.output  # whole: which child did not stop


def _program(process: psutil.Process) -> str:
    """The console script a child runs (its interpreter's first argument)."""
    return Path(process.cmdline()[1]).name


def _wait_connected(dashboard: re.Match[str] | None) -> None:
    """Until the gateway of this dashboard link reaches its node."""
    assert dashboard is not None
    url, token = dashboard.groups()
    headers = {'Authorization': f'Bearer {token}'}
    wait_until(
        lambda: httpx.get(f'{url}/api/health', headers=headers).json()['connected'],
        'the gateway connected',
    )


def test_a_gateway_deaf_to_its_node_after_a_hold_up_is_started_again() -> None:
    """The web gateway held up with the node (SIGSTOP), then let go while the node stays
    stopped, exits 3: the launcher starts a new one, which serves with the same admin token,
    and still stops cleanly."""
    demo = DemoProcess('task-manager-demo', LAUNCHER)
    try:
        dashboard = demo.wait_for_line(r'dashboard: http', START_TIMEOUT_SEC)
        demo.wait_for_line(r'^Ctrl-C stops', START_TIMEOUT_SEC)
        _wait_connected(re.search(r'(http://\S+)/\?token=(\S+)', dashboard))
        children = {_program(p): p for p in psutil.Process(demo.pid).children()}
        node, web = children['task-manager'], children['task-manager-web']
        node.suspend()
        web.suspend()
        try:
            time.sleep(HELD_UP_SEC + 1.5)  # the hold-up is this test's input, not a wait
            web.resume()
            demo.wait_for_line(r'web exited with code 3: starting it again', ANSWER_SEC + 20)
        finally:
            node.resume()
        wait_until(lambda: demo.output.count('dashboard: http') == 2, 'a new gateway serving')
        first, again = re.finditer(r'(http://\S+)/\?token=(\S+)', demo.output)
        assert again[2] == first[2]  # the token the dashboard holds still opens it
        _wait_connected(again)

        demo.child.process.send_signal(signal.SIGTERM)

        assert demo.wait_exit(STOP_TIMEOUT_SEC) == 0, demo.output
    finally:
        if demo.child.exit_code is None:
            demo.stop()
