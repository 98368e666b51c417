"""Console script `task-manager-fleet` (`make fleet`): a fleet of simulated robots on a broker.

Starts a local mosquitto (an account per robot, one for the cloud's scripts, one for the fleet
console and a read-only `observer`: the broker ties a client id to its account, so one account
holds one connection; each robot may write only its own outgoing topics), then for each robot,
in a ROS domain of its own: the simulated robot, a Task Manager with the demo's tasks, and its
MQTT bridge; and the fleet console, on SQLite or (`--database postgres`) a local PostgreSQL
server started beside them. Once all are ready it prints the broker URL, the files that hold
the passwords (never a password: a banner ends up in logs and scrollback, a command line in
`ps`), the console's link, the database and the example to run, then streams their logs.
Ctrl-C stops everything it started.
"""

import argparse
import os
import re
import sys
import textwrap
from pathlib import Path

from task_manager_console.store.local_postgres import READY_LINE as POSTGRES_READY_LINE
from task_manager_console.store.local_postgres import PostgresError, PostgresServer
from task_manager_mqtt.broker import CLOUD_USER, OBSERVER_USER, READY_LINE, MosquittoBroker
from task_manager_mqtt.settings import DEFAULT_PREFIX

from task_manager_demo.children import Child, Events
from task_manager_demo.run_demo import (
    READY_TIMEOUT_SEC,
    default_params_file,
    find_executable,
    shown_path,
    start_robot,
)
from task_manager_demo.supervisor import Supervisor, supervise_demo

BRIDGE_EXECUTABLE = ('task-manager-mqtt', 'task_manager_mqtt')
BRIDGE_READY = re.compile(r'connected to the broker')
BROKER_READY = re.compile(READY_LINE)
CONSOLE_EXECUTABLE = ('task-manager-console', 'task_manager_console')
CONSOLE_USER = 'console'
"""The console's broker account: its own, as the example scripts keep `cloud`."""
CONSOLE_READY = re.compile(r'^dashboard: (?P<console>http://\S+\?token=\S+)$')
POSTGRES_READY = re.compile(POSTGRES_READY_LINE)
DATABASES = ('sqlite', 'postgres')
DEFAULT_ROBOTS = 3
DEFAULT_PORT = 0
"""Any free port: a system mosquitto (Debian starts one when installed) may hold 1883."""
DEFAULT_FIRST_DOMAIN = 1
RULE = '=' * 78
EXAMPLE = Path('examples') / 'fleet_mission.py'
PASSWORD_FILE = 'mqtt_password'
"""In the folder of each account (<folder>/<robot_id>/, <folder>/cloud/, ...)."""
CONSOLE_DATABASE = 'fleet'
"""The console's database on the local PostgreSQL server."""


class Fleet(Supervisor):
    def __init__(self, options: argparse.Namespace, events: Events) -> None:
        super().__init__(events, prefix_lines=True)
        self.robot_ids = [f'robot{n}' for n in range(1, options.robots + 1)]
        self.domains = {r: options.first_domain + i for i, r in enumerate(self.robot_ids)}
        self.folder: Path = options.folder
        self.params_file = default_params_file()
        self.robot_args: list[str] = options.robot_arg or []
        self.broker = MosquittoBroker(
            self.folder / 'broker',
            self.robot_ids,
            port=options.broker_port,
            clouds=(CLOUD_USER, CONSOLE_USER),
            observers=(OBSERVER_USER,),
        )
        self.cloud_password_file = self.folder / CLOUD_USER / PASSWORD_FILE
        self.observer_password_file = self.folder / OBSERVER_USER / PASSWORD_FILE
        self.console_port: int = options.console_port
        self.postgres = (
            PostgresServer(self.folder / 'postgres') if options.database == 'postgres' else None
        )
        self.database_url = (
            self.postgres.url(CONSOLE_DATABASE)
            if self.postgres
            else f'sqlite:///{(self.folder / CONSOLE_USER / "fleet.sqlite").absolute()}'
        )

    def start(self) -> None:
        write_password(self.cloud_password_file, self.broker.passwords[CLOUD_USER])
        write_password(self.observer_password_file, self.broker.passwords[OBSERVER_USER])
        broker = self.start_child('broker', self.broker.command, BROKER_READY)
        needs = [broker]
        if self.postgres is not None:
            try:
                self.postgres.make_cluster(CONSOLE_DATABASE)
            except PostgresError as error:  # e.g. a folder the server's user cannot reach
                raise SystemExit(f'task-manager-fleet: {error}') from None
            needs.append(self.start_child('postgres', self.postgres.command, POSTGRES_READY))
        for robot_id in self.robot_ids:
            self._start_robot(robot_id)
        self._start_console(needs)

    def _start_console(self, needs: list[Child]) -> None:
        """Once the broker (and the database) answer: the console, with an account of its own."""
        home = self.folder / CONSOLE_USER
        password_file = home / PASSWORD_FILE
        write_password(password_file, self.broker.passwords[CONSOLE_USER])
        console = [
            find_executable(*CONSOLE_EXECUTABLE),
            '--broker-url',
            f'mqtt://{CONSOLE_USER}@127.0.0.1:{self.broker.port}',
            '--password-file',
            str(password_file),
            '--database',
            self.database_url,
            '--port',
            str(self.console_port),
        ]
        self.start_when_ready('console', console, CONSOLE_READY, needs, {'ROS_HOME': str(home)})

    def _start_robot(self, robot_id: str) -> None:
        home = self.folder / robot_id
        home.mkdir(parents=True, exist_ok=True)
        password_file = home / PASSWORD_FILE
        write_password(password_file, self.broker.passwords[robot_id])
        env = {'ROS_DOMAIN_ID': str(self.domains[robot_id]), 'ROS_HOME': str(home)}
        start_robot(self, self.params_file, f'{robot_id}/', env, self.robot_args)
        bridge = [
            find_executable(*BRIDGE_EXECUTABLE),
            '--robot-id',
            robot_id,
            '--broker-url',
            f'mqtt://{robot_id}@127.0.0.1:{self.broker.port}',
            '--password-file',
            str(password_file),
        ]
        self.start_child(f'{robot_id}/bridge', bridge, BRIDGE_READY, env)

    def banner(self, ready: dict[str, str]) -> str:
        url = f'mqtt://{CLOUD_USER}@127.0.0.1:{self.broker.port}'
        password_file = shown_path(self.cloud_password_file)
        python = shown_path(Path(sys.executable))
        robots = ', '.join(f'{r} (ROS domain {d})' for r, d in self.domains.items())
        return '\n'.join(
            [
                RULE,
                f'Fleet ready: {len(self.robot_ids)} simulated robots, each with a Task Manager '
                'and its MQTT bridge',
                f'  broker: {url}',
                f"          the cloud's password is in {password_file}",
                f'          a read-only account for watchers (mosquitto_sub): {OBSERVER_USER},',
                f'          its password in {shown_path(self.observer_password_file)}',
                '          (the console and each robot have an account of their own, see '
                f'{shown_path(self.broker.folder / "acl")})',
                textwrap.fill(
                    robots, width=len(RULE), initial_indent='  robots: ', subsequent_indent=' ' * 10
                ),
                textwrap.fill(
                    f'{DEFAULT_PREFIX}/<robot_id>/request, reply, result, event, active_tasks, '
                    'tasks, connection, dead_letter',
                    width=len(RULE),
                    initial_indent='  topics: ',
                    subsequent_indent=' ' * 10,
                ),
                f'  console: {ready["console"]}',
                f'  database: {self.database_url}',
                '',
                'In a second terminal, send a mission to every robot and watch the fleet:',
                f'  {python} {EXAMPLE} --broker-url {url} \\',
                f'      --password-file {password_file}',
                '',
                'Ctrl-C stops the broker, the robots, their Task Managers and bridges, the console'
                + (' and its database.' if self.postgres else '.'),
                RULE,
            ]
        )


def write_password(path: Path, password: str) -> None:
    """Readable by its owner only, from its creation on."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.unlink(missing_ok=True)
    descriptor = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(descriptor, 'w') as file:
        file.write(password + '\n')


def broker_demo_parser(
    prog: str, description: str | None, folder_name: str, folder_holds: str
) -> argparse.ArgumentParser:
    """The options of a demo on a local broker: --broker-port, --folder (which holds
    `folder_holds`, $ROS_HOME/task_manager/<folder_name> by default) and --ready-timeout."""
    ros_home = Path(os.environ.get('ROS_HOME') or Path.home() / '.ros')
    parser = argparse.ArgumentParser(prog=prog, description=description)
    parser.add_argument(
        '--broker-port', type=int, default=DEFAULT_PORT, help='default 0: any free one'
    )
    parser.add_argument(
        '--folder',
        type=Path,
        default=ros_home / 'task_manager' / folder_name,
        help=f'{folder_holds} ($ROS_HOME/task_manager/{folder_name})',
    )
    parser.add_argument('--ready-timeout', type=float, default=READY_TIMEOUT_SEC)
    return parser


def parse_arguments(argv: list[str] | None) -> argparse.Namespace:
    parser = broker_demo_parser(
        'task-manager-fleet', __doc__, 'fleet', "broker files and each robot's ROS_HOME"
    )
    parser.add_argument('--robots', type=int, default=DEFAULT_ROBOTS, help='how many (3)')
    parser.add_argument(
        '--first-domain',
        type=int,
        default=DEFAULT_FIRST_DOMAIN,
        help='ROS domain of robot1; robot2 gets the next, ... (1)',
    )
    parser.add_argument(
        '--robot-arg',
        action='append',
        metavar='NAME:=VALUE',
        help='a ROS parameter of every simulated robot (e.g. linear_speed:=4.0)',
    )
    parser.add_argument(
        '--console-port', type=int, default=0, help="the console's port; default 0: any free one"
    )
    parser.add_argument(
        '--database',
        choices=DATABASES,
        default='sqlite',
        help="the console's fleet history: a SQLite file in the folder, or a PostgreSQL server "
        "of its own started beside the broker (Debian's postgresql); %(default)s",
    )
    options = parser.parse_args(argv)
    if options.robots < 1:
        parser.error('--robots: at least 1')
    return options


def main(argv: list[str] | None = None) -> int:
    return supervise_demo(Fleet, parse_arguments(argv), 'task-manager-fleet: the fleet has stopped')


if __name__ == '__main__':
    sys.exit(main())
