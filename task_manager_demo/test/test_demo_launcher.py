"""`task-manager-demo`: stops both children on a signal, leaves none behind when killed, and
fails loudly when a child dies early."""

import signal
import sys
from pathlib import Path

import psutil
import pytest

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
