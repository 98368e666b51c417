"""Fixtures of the console's tests: the fleet history on SQLite and on a real PostgreSQL server
(one per test session, a database per test), a real mosquitto with an account per robot and
one for the console, the console as users run it, and two of the demo's robots on the broker."""

import itertools
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from task_manager_mqtt.broker import CLOUD_USER
from task_manager_mqtt.testing import BRIDGE_EXECUTABLE, CONNECTED_LINE, BrokerProcess

from task_manager.testing.domains import console_robot_domains
from task_manager.testing.process import NodeProcess
from task_manager_console.doors_testing import ConsoleProcess
from task_manager_console.fleet import Fleet
from task_manager_console.simulation.robot import SimulatedRobot
from task_manager_console.simulation.robot_loop import TIMEOUT_SEC
from task_manager_console.store.fleet_history import FleetHistory
from task_manager_console.store.local_postgres import PostgresServer
from task_manager_console.testing import CONSOLE_USER, ROBOTS, postgres_server
from task_manager_demo.run_demo import ROBOT_READY, TASK_MANAGER_READY, default_params_file
from task_manager_demo.testing import robot_command

DATABASES = ('sqlite', 'postgresql')
DEMO_START_TIMEOUT_SEC = 30.0
_numbers = itertools.count(1)


@pytest.fixture(scope='session')
def postgres() -> Iterator[PostgresServer]:
    """A PostgreSQL server of Debian's binaries, for the whole session."""
    with postgres_server() as server:
        yield server


@pytest.fixture(params=DATABASES)
def database_url(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    """A new, empty database: a SQLite file, or a database on the PostgreSQL server."""
    if request.param == 'sqlite':
        return f'sqlite:///{tmp_path / "fleet.sqlite"}'
    server: PostgresServer = request.getfixturevalue('postgres')
    return server.create_database(f'fleet_test_{next(_numbers)}')


@pytest.fixture
def history(database_url: str) -> Iterator[FleetHistory]:
    history = FleetHistory.open(database_url)
    yield history
    history.close()


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[BrokerProcess]:
    """A mosquitto with robot1-3 and the cloud accounts `console` and `cloud`."""
    broker = BrokerProcess(tmp_path / 'broker', robots=ROBOTS, clouds=[CONSOLE_USER, CLOUD_USER])
    broker.start()
    yield broker
    broker.stop()


@pytest.fixture
def start_console(broker: BrokerProcess, database_url: str) -> Iterator[Callable[..., Fleet]]:
    """Start a Fleet (the console in this process) on the test's broker and database, as
    the `console` account; each one started is closed at the end."""
    started: list[Fleet] = []

    def start(**options: Any) -> Fleet:
        history = FleetHistory.open(database_url)
        fleet = Fleet(broker.url(CONSOLE_USER), history, **options)
        started.append(fleet)
        fleet.start(TIMEOUT_SEC)
        return fleet

    yield start
    for fleet in started:
        fleet.close()
        fleet.history.close()


@pytest.fixture
def start_robot_on(broker: BrokerProcess) -> Iterator[Callable[..., SimulatedRobot]]:
    """Connect a simulated robot (its account on the test's broker); closed at the end."""
    robots: list[SimulatedRobot] = []

    def start(robot_id: str, **options: Any) -> SimulatedRobot:
        robot = SimulatedRobot(broker.port, robot_id, broker.passwords[robot_id], **options)
        robots.append(robot)
        robot.connect()
        return robot

    yield start
    for robot in robots:
        robot.close()


@pytest.fixture
def console(broker: BrokerProcess, tmp_path: Path) -> Iterator[ConsoleProcess]:
    """`task-manager-console` as users run it, on the test's broker and a SQLite file."""
    console = ConsoleProcess(broker, f'sqlite:///{tmp_path / "fleet.sqlite"}', tmp_path / 'c')
    yield console
    assert console.stop() == 0, '\n'.join(console.lines)


def demo_robot(
    robot_id: str, domain: int, broker: BrokerProcess, folder: Path
) -> list[NodeProcess]:
    """The demo's simulated robot, its Task Manager (the demo's tasks) and its bridge, in ROS
    domain `domain`; started, not waited for."""
    env = {'ROS_DOMAIN_ID': str(domain)}
    bridge = [
        BRIDGE_EXECUTABLE, '--robot-id', robot_id, '--broker-url', broker.url(robot_id),
        '--state-file', str(folder / f'{robot_id}.acked'),
    ]  # fmt: skip
    return [
        NodeProcess(None, command=robot_command(), env=env),
        NodeProcess(default_params_file(), env=env),
        NodeProcess(None, command=bridge, env=env),
    ]


@pytest.fixture
def two_demo_robots(broker: BrokerProcess, tmp_path: Path) -> Iterator[None]:
    """robot1 and robot2, each the demo's robot, Task Manager and bridge in a ROS domain of its
    own: two of this run's domains, this worker's (task_manager.testing.domains)."""
    processes = [
        process
        for robot_id, domain in zip(('robot1', 'robot2'), console_robot_domains(), strict=True)
        for process in demo_robot(robot_id, domain, broker, tmp_path)
    ]
    try:
        ready_lines = [ROBOT_READY.pattern, TASK_MANAGER_READY.pattern, CONNECTED_LINE] * 2
        for process, ready in zip(processes, ready_lines, strict=True):
            process.wait_for_log(ready, DEMO_START_TIMEOUT_SEC)
        yield
    finally:
        for process in reversed(processes):
            process.stop()
