"""What the console benchmark runs: a local mosquitto with an account per robot and the
console's, a database (a SQLite file, or a local PostgreSQL server of Debian's binaries),
`task-manager-console` as users start it, and simulated robots (no ROS) on one thread here."""

import contextlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
from task_manager_console.doors_testing import ConsoleProcess, wait_for
from task_manager_console.simulation.robot import SimulatedRobot, connect_all
from task_manager_console.simulation.robot_loop import RobotLoop
from task_manager_console.store.fleet_history import FleetHistory
from task_manager_console.testing import CONSOLE_USER, postgres_server
from task_manager_mqtt.testing import BrokerProcess
from task_manager_web.doors_testing import ADMIN

from bench.harness.replies import BenchError

DATABASES = ('sqlite', 'postgresql')
TASKS = ('drive', 'dock', 'inspect')
"""The tasks each simulated robot declares."""


@dataclass
class RunningFleet:
    """The broker, the console and its database, the robots; `http`: the console's doors
    with an admin token; `history`: the bench's own connection to the console's database."""

    database: str
    broker: BrokerProcess
    database_url: str
    console: ConsoleProcess
    folder: Path
    loop: RobotLoop
    robots: list[SimulatedRobot]
    history: FleetHistory
    http: httpx.Client

    def restart_console(self) -> None:
        """Start the console again, as before (after `console.stop()`)."""
        self.http.close()
        self.console = ConsoleProcess(self.broker, self.database_url, self.folder / 'console')
        self.http = self.console.client(ADMIN)

    def robots_listed(self) -> list[dict[str, Any]]:
        """GET /api/robots."""
        answer = self.http.get('/api/robots')
        if answer.status_code != 200:
            raise BenchError(f'GET /api/robots: {answer.status_code} {answer.text[:200]}')
        robots: list[dict[str, Any]] = answer.json()
        return robots


@contextlib.contextmanager
def running_fleet(log_dir: Path, database: str, robot_count: int) -> Iterator[RunningFleet]:
    """Everything started, the console listing every robot ONLINE; stopped in reverse order."""
    folder = log_dir / f'console_{database}'
    robot_ids = [f'robot{number:03d}' for number in range(1, robot_count + 1)]
    with contextlib.ExitStack() as stack:
        broker = BrokerProcess(folder / 'broker', robot_ids, clouds=[CONSOLE_USER])
        broker.start()
        stack.callback(broker.stop)
        if database == 'sqlite':
            database_url = f'sqlite:///{folder / "fleet.sqlite"}'
        else:  # a folder of its own under /tmp, where the `postgres` user reaches it
            server = stack.enter_context(postgres_server())
            database_url = server.create_database('fleet')
        history = FleetHistory.open(database_url)
        stack.callback(history.close)
        console = ConsoleProcess(broker, database_url, folder / 'console')
        loop = RobotLoop()
        stack.callback(loop.close)
        robots = [
            SimulatedRobot(
                broker.port, i, broker.passwords[i], tasks=TASKS, keepalive_sec=60, loop=loop
            )
            for i in robot_ids
        ]
        running = RunningFleet(
            database,
            broker,
            database_url,
            console,
            folder,
            loop,
            robots,
            history,
            console.client(ADMIN),
        )
        stack.callback(lambda: running.console.stop())
        stack.callback(lambda: running.http.close())
        connect_all(robots)
        for robot in robots:
            stack.callback(robot.close)
        wait_for(
            running.robots_listed,
            lambda listed: sum(r['connection_state'] == 'ONLINE' for r in listed) == robot_count,
            f'{robot_count} robots ONLINE on the console',
        )
        yield running
