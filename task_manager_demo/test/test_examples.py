"""The examples run against the demo robot and the Task Manager, as the README says."""

import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from task_manager.testing.process import NodeProcess
from task_manager_demo.testing import DemoProcess, robot_command

REPO = Path(__file__).resolve().parents[2]
PARAMS = REPO / 'task_manager_demo' / 'params' / 'demo_tasks.yaml'
START_TIMEOUT_SEC = 30.0
RUN_TIMEOUT_SEC = 60.0


@pytest.fixture(scope='module')
def demo() -> Iterator[None]:
    """A fast simulated robot and the Task Manager with the demo's tasks."""
    robot = DemoProcess('robot', robot_command('linear_speed:=4.0', 'angular_speed:=8.0'))
    task_manager = NodeProcess(PARAMS)
    try:
        task_manager.wait_for_log(r'Task Manager ready', START_TIMEOUT_SEC)
        yield
    finally:
        assert task_manager.stop() == 0, '\n'.join(task_manager.log_lines)
        assert robot.stop() == 0, robot.output


def run_example(name: str, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(REPO / 'examples' / name), *args],
        capture_output=True,
        text=True,
        timeout=RUN_TIMEOUT_SEC,
        check=False,
    )


def test_send_task(demo: None) -> None:
    done = run_example('send_task.py', '0.5', '0.5')

    assert done.returncode == 0, done.stdout + done.stderr
    assert 'DONE' in done.stdout


def test_send_mission_skips_the_broken_camera(demo: None) -> None:
    done = run_example('send_mission.py')

    assert done.returncode == 0, done.stdout + done.stderr
    assert 'ERROR (skipped)' in done.stdout and 'mission DONE' in done.stdout


def test_navigation_demo_pre_empts_then_runs_a_mission(demo: None) -> None:
    done = run_example('navigation_demo.py')

    assert done.returncode == 0, done.stdout + done.stderr
    assert 'the navigation it pre-empted: CANCELED' in done.stdout
    assert 'mission of 7 subtasks: DONE' in done.stdout


def test_tracker_sees_tasks_started_elsewhere(demo: None) -> None:
    tracker = subprocess.Popen(
        [sys.executable, str(REPO / 'examples' / 'track_active_tasks.py'), '5'],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,  # apart: Fast DDS logs an error there now and then (a shared
        text=True,  # memory port another process holds), which is not the first line
    )
    assert tracker.stdout is not None
    assert tracker.stdout.readline().startswith('watching')  # connected before the task
    run_example('send_task.py', '0.2', '0.0')

    output, errors = tracker.communicate(timeout=RUN_TIMEOUT_SEC)

    assert 'navigation/navigate_to_pose (IN_PROGRESS)' in output, output + errors
    assert 'result  navigation/navigate_to_pose' in output


def test_mission_file_with_taskctl(demo: None) -> None:
    done = subprocess.run(
        [
            str(Path(sys.executable).with_name('taskctl')),
            'mission',
            str(REPO / 'examples' / 'mission.yaml'),
        ],
        capture_output=True,
        text=True,
        timeout=RUN_TIMEOUT_SEC,
        check=False,
    )

    assert done.returncode == 0, done.stdout + done.stderr
