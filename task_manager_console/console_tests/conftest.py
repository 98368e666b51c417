"""Fixtures of the console's tests: the fleet history on SQLite and on a real PostgreSQL server
(one per test session, a database per test), a real mosquitto with an account per robot and
one for the console."""

import itertools
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from task_manager_mqtt.broker import CLOUD_USER
from task_manager_mqtt.testing import BrokerProcess

from task_manager_console.fleet import Fleet
from task_manager_console.simulation.robot import SimulatedRobot
from task_manager_console.store.fleet_history import FleetHistory
from task_manager_console.store.local_postgres import PostgresServer
from task_manager_console.testing import CONSOLE_USER, ROBOTS, TIMEOUT_SEC, postgres_server

DATABASES = ('sqlite', 'postgresql')
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
