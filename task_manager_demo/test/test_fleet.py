"""`task-manager-fleet` (`make fleet`): three robots, each in its own ROS domain with its Task
Manager and MQTT bridge, on one broker; one cloud client drives them all, the fleet console
(an account of its own) lists them, an observer reads and writes nothing; Ctrl-C stops all."""

import os
import re
import shutil
import subprocess
import sys
import tempfile
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import psutil
import pytest
from task_manager_console.doors_testing import wait_for
from task_manager_console.store.local_postgres import postgres_bin
from task_manager_mqtt.broker import OBSERVER_USER
from task_manager_mqtt.fleet_client import FleetClient
from task_manager_mqtt.fleet_types import FleetTask
from task_manager_mqtt.testing import RawClient
from task_manager_mqtt.topics import Topics

from task_manager_demo.testing import DemoProcess

pytestmark = pytest.mark.ros
REPO = Path(__file__).resolve().parents[2]
ROBOTS = ['robot1', 'robot2', 'robot3']
TASKS_PER_ROBOT = 200
READY_TIMEOUT_SEC = 60.0
RESULT_TIMEOUT_SEC = 60.0
FAST_ROBOT = ('--robot-arg', 'linear_speed:=4.0', '--robot-arg', 'angular_speed:=8.0')
CONSOLE_LINE = r'^  console: http://127\.0\.0\.1:\d+/\?token=[\w-]+$'
DATABASE_LINE = r'^  database: '
TAKEN_OVER = 'Client {} already connected, closing old connection'
"""What mosquitto logs when a second connection of an account pushes the first off."""
NOT_AUTHORIZED = 'Not authorized'


def fleet_command(folder: Path, *options: str) -> list[str]:
    # domains apart from those of the test runs (1-90, task_manager.testing.domains)
    first_domain = 120 + int(os.environ['TASK_MANAGER_TEST_DOMAIN'])
    return [
        str(Path(sys.executable).with_name('task-manager-fleet')),
        '--broker-port', '0',
        '--first-domain', str(first_domain),
        '--folder', str(folder),
        *FAST_ROBOT,
        *options,
    ]  # fmt: skip


def test_one_cloud_client_drives_three_robots(tmp_path: Path) -> None:
    fleet = DemoProcess('fleet', fleet_command(tmp_path))
    running: list[psutil.Process] = []
    try:
        line = fleet.wait_for_line(r'  broker: mqtt://', READY_TIMEOUT_SEC)
        url = re.search(r'(mqtt://\S+)', line)[1]  # type: ignore[index]
        line = fleet.wait_for_line(r"the cloud's password is in ", READY_TIMEOUT_SEC)
        password_file = Path(line.rsplit(' ', 1)[1])  # relative to the working directory
        password = password_file.read_text().strip()
        assert password and password_file.stat().st_mode & 0o077 == 0
        console = fleet.wait_for_line(CONSOLE_LINE, READY_TIMEOUT_SEC).split()[1]
        assert fleet.wait_for_line(DATABASE_LINE, READY_TIMEOUT_SEC) == (
            f'  database: sqlite:///{tmp_path}/console/fleet.sqlite'
        )
        running = processes_of(fleet)
        check_observer(tmp_path, int(url.rsplit(':', 1)[1]))
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
        check_console_lists_robots(console)
    finally:
        code = fleet.stop(timeout_sec=60.0)
    assert code == 0, fleet.output
    assert 'the fleet has stopped' in fleet.output
    assert password not in fleet.output  # in a file only, not in the banner nor a command line
    # the console has an account of its own: the cloud's clients never pushed it off
    assert not [a for a in ('cloud', 'console') if TAKEN_OVER.format(a) in fleet.output]
    assert not alive(running), alive(running)


def processes_of(fleet: DemoProcess) -> list[psutil.Process]:
    """Every process the launcher runs (the broker, the robots' nodes, the console, ...)."""
    return psutil.Process(fleet.pid).children(recursive=True)


def alive(processes: list[psutil.Process]) -> list[psutil.Process]:
    return [p for p in processes if p.is_running() and p.status() != psutil.STATUS_ZOMBIE]


def check_console_lists_robots(console: str, robots: list[str] = ROBOTS) -> None:
    """The console's link (its token in it) opens GET /api/robots: the robots, ONLINE."""
    token = console.split('?token=')[1]
    base_url = console.split('?')[0]
    with httpx.Client(base_url=base_url, headers={'Authorization': f'Bearer {token}'}) as http:
        listed = wait_for(
            lambda: http.get('/api/robots').json(),
            lambda rs: (
                sorted(r['robot_id'] for r in rs if r['connection_state'] == 'ONLINE') == robots
            ),
            f'the console lists {robots} ONLINE',
        )
    assert len(listed) == len(robots)


def check_observer(folder: Path, port: int) -> None:
    """The observer account reads what the robots send, and may publish nothing."""
    password = (folder / OBSERVER_USER / 'mqtt_password').read_text().strip()
    topics = [Topics('task_manager/v1', '+').connection]
    with RawClient(port, OBSERVER_USER, password, topics=topics) as observer:
        observer.wait_for(
            lambda received: {r.topic.split('/')[2] for r in received} >= set(ROBOTS),
            "the robots' connection documents",
        )
        request = Topics('task_manager/v1', ROBOTS[0]).request
        assert observer.publish(request, '{"op": "stop"}') == NOT_AUTHORIZED


@pytest.fixture
def reachable_folder() -> Iterator[Path]:
    """A new folder under /tmp that the `postgres` user reaches (pytest's tmp_path is root's
    only, when root runs the tests), removed at the end."""
    folder = Path(tempfile.mkdtemp(prefix='fleet-test-'))
    folder.chmod(0o755)
    yield folder
    shutil.rmtree(folder, ignore_errors=True)


def test_fleet_with_postgres(reachable_folder: Path) -> None:
    """`make fleet FLEET_DB=postgres`: the console on a PostgreSQL server of the fleet's own,
    whose printed URL psql accepts; Ctrl-C stops the server too. One robot is enough here."""
    tmp_path = reachable_folder
    fleet = DemoProcess('fleet', fleet_command(tmp_path, '--database', 'postgres', '--robots', '1'))
    running: list[psutil.Process] = []
    try:
        console = fleet.wait_for_line(CONSOLE_LINE, READY_TIMEOUT_SEC).split()[1]
        line = fleet.wait_for_line(DATABASE_LINE, READY_TIMEOUT_SEC)
        database = re.fullmatch(r'  database: (postgresql://console@127\.0\.0\.1:\d+/fleet)', line)
        assert database, line
        running = processes_of(fleet)
        assert any(p.name() == 'postgres' for p in running), running
        check_console_lists_robots(console, ROBOTS[:1])
        tables = psql(database[1], "SELECT count(*) FROM pg_tables WHERE tablename = 'results'")
        assert tables == '1'  # the console made its schema there
    finally:
        code = fleet.stop(timeout_sec=60.0)
    assert code == 0, fleet.output
    assert (tmp_path / 'postgres' / 'data' / 'PG_VERSION').exists()
    assert not (tmp_path / 'postgres' / 'data' / 'postmaster.pid').exists()  # a clean stop
    assert not alive(running), alive(running)


def psql(url: str, query: str) -> str:
    """One value, as Debian's psql prints it (found where the server's binaries are)."""
    done = subprocess.run(
        [str(postgres_bin() / 'psql'), url, '--tuples-only', '--no-align', '-c', query],
        capture_output=True,
        text=True,
        timeout=30,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    return done.stdout.strip()


def check_results(results: list[tuple[FleetTask, dict[str, Any]]]) -> None:
    """Each ended DONE, on the robot it was sent to (its photo counter is per robot)."""
    assert all(r['status'] == 'DONE' and r['task_id'] == t.task_id for t, r in results)
    per_robot = Counter(task.robot_id for task, _ in results)
    assert per_robot == dict.fromkeys(ROBOTS, TASKS_PER_ROBOT)
    for robot_id in ROBOTS:
        photo_ids = sorted(r['result']['photo_id'] for t, r in results if t.robot_id == robot_id)
        assert photo_ids == sorted(f'front-{n:04d}' for n in range(1, TASKS_PER_ROBOT + 1))
