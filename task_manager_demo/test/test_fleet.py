"""`task-manager-fleet` (`make fleet`): three robots, each in its own ROS domain with its Task
Manager and MQTT bridge, on one broker; one cloud client drives them all."""

import os
import re
import subprocess
import sys
from collections import Counter
from pathlib import Path
from typing import Any

import pytest
from task_manager_mqtt.fleet_client import FleetClient, FleetTask

from task_manager_demo.testing import DemoProcess

pytestmark = pytest.mark.ros
REPO = Path(__file__).resolve().parents[2]
ROBOTS = ['robot1', 'robot2', 'robot3']
TASKS_PER_ROBOT = 200
READY_TIMEOUT_SEC = 60.0
RESULT_TIMEOUT_SEC = 60.0
FAST_ROBOT = ('--robot-arg', 'linear_speed:=4.0', '--robot-arg', 'angular_speed:=8.0')


def fleet_command(folder: Path) -> list[str]:
    # domains apart from those of the test processes (1-100, see conftest.py)
    first_domain = 120 + int(os.environ['TASK_MANAGER_TEST_DOMAIN'])
    return [
        str(Path(sys.executable).with_name('task-manager-fleet')),
        '--broker-port', '0',
        '--first-domain', str(first_domain),
        '--folder', str(folder),
        *FAST_ROBOT,
    ]  # fmt: skip


def test_one_cloud_client_drives_three_robots(tmp_path: Path) -> None:
    fleet = DemoProcess('fleet', fleet_command(tmp_path))
    try:
        line = fleet.wait_for_line(r'  broker: mqtt://', READY_TIMEOUT_SEC)
        url = re.search(r'(mqtt://\S+)', line)[1]  # type: ignore[index]
        line = fleet.wait_for_line(r"the cloud's password is in ", READY_TIMEOUT_SEC)
        password_file = Path(line.rsplit(' ', 1)[1])  # relative to the working directory
        password = password_file.read_text().strip()
        assert password and password_file.stat().st_mode & 0o077 == 0
        with FleetClient(url, password=password) as cloud:
            assert cloud.wait_online(ROBOTS, READY_TIMEOUT_SEC), cloud.robots
            photos = [
                cloud.start_task(robot_id, 'camera/take_photo', {'camera': 'front'})
                for _ in range(TASKS_PER_ROBOT)
                for robot_id in ROBOTS
            ]
            results = [(task, task.result(RESULT_TIMEOUT_SEC)) for task in photos]
            check_results(results)

        example = subprocess.run(
            [
                sys.executable,
                str(REPO / 'examples' / 'fleet_mission.py'),
                '--broker-url',
                url,
                '--password-file',
                str(password_file),
            ],
            capture_output=True,
            text=True,
            timeout=RESULT_TIMEOUT_SEC,
            check=False,
        )
        assert example.returncode == 0, example.stdout + example.stderr
        assert all(f'{r}: mission DONE' in example.stdout for r in ROBOTS), example.stdout
    finally:
        code = fleet.stop(timeout_sec=60.0)
    assert code == 0, fleet.output
    assert 'the fleet has stopped' in fleet.output
    assert password not in fleet.output  # in a file only, not in the banner nor a command line


def check_results(results: list[tuple[FleetTask, dict[str, Any]]]) -> None:
    """Each ended DONE, on the robot it was sent to (its photo counter is per robot)."""
    assert all(r['status'] == 'DONE' and r['task_id'] == t.task_id for t, r in results)
    per_robot = Counter(task.robot_id for task, _ in results)
    assert per_robot == dict.fromkeys(ROBOTS, TASKS_PER_ROBOT)
    for robot_id in ROBOTS:
        photo_ids = sorted(r['result']['photo_id'] for t, r in results if t.robot_id == robot_id)
        assert photo_ids == sorted(f'front-{n:04d}' for n in range(1, TASKS_PER_ROBOT + 1))
