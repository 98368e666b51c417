"""Console script `task-manager-fleet` (`make fleet`): a fleet of simulated robots on a broker.

Starts a local mosquitto (an account per robot and one for the cloud; each robot may write
only its own outgoing topics), then for each robot, in a ROS domain of its own: the simulated
robot, a Task Manager with the demo's tasks, and its MQTT bridge. Once all are ready it
prints the broker URL, the file that holds the cloud's password (never the password: a
banner ends up in logs and scrollback, a command line in `ps`) and the example to run, then
streams their logs. Ctrl-C stops everything it started.
"""

import argparse
import os
import re
import sys
import textwrap
from pathlib import Path

from task_manager_mqtt.broker import CLOUD_USER, READY_LINE, MosquittoBroker
from task_manager_mqtt.settings import DEFAULT_PREFIX

from task_manager.discovery import use_quick_discovery
from task_manager_demo.children import Events
from task_manager_demo.run_demo import (
    READY_TIMEOUT_SEC,
    ROBOT_EXECUTABLE,
    ROBOT_READY,
    TASK_MANAGER_EXECUTABLE,
    TASK_MANAGER_READY,
    default_params_file,
    find_executable,
    shown_path,
)
from task_manager_demo.supervisor import Supervisor, supervise

BRIDGE_EXECUTABLE = ('task-manager-mqtt', 'task_manager_mqtt')
BRIDGE_READY = re.compile(r'connected to the broker')
BROKER_READY = re.compile(READY_LINE)
DEFAULT_ROBOTS = 3
DEFAULT_PORT = 0
"""Any free port: a system mosquitto (Debian starts one when installed) may hold 1883."""
DEFAULT_FIRST_DOMAIN = 1
RULE = '=' * 78
EXAMPLE = Path('examples') / 'fleet_mission.py'
PASSWORD_FILE = 'mqtt_password'
"""In the folder of each account (<folder>/<robot_id>/, <folder>/cloud/)."""


class Fleet(Supervisor):
    def __init__(self, options: argparse.Namespace, events: Events) -> None:
        super().__init__(events, prefix_lines=True)
        self.robot_ids = [f'robot{n}' for n in range(1, options.robots + 1)]
        self.domains = {r: options.first_domain + i for i, r in enumerate(self.robot_ids)}
        self.folder: Path = options.folder
        self.params_file = default_params_file()
        self.robot_args: list[str] = options.robot_arg or []
        self.broker = MosquittoBroker(
            self.folder / 'broker', self.robot_ids, port=options.broker_port
        )
        self.cloud_password_file = self.folder / CLOUD_USER / PASSWORD_FILE

    def start(self) -> None:
        write_password(self.cloud_password_file, self.broker.passwords[CLOUD_USER])
        self.start_child('broker', self.broker.command, BROKER_READY)
        for robot_id in self.robot_ids:
            self._start_robot(robot_id)

    def _start_robot(self, robot_id: str) -> None:
        home = self.folder / robot_id
        home.mkdir(parents=True, exist_ok=True)
        password_file = home / PASSWORD_FILE
        write_password(password_file, self.broker.passwords[robot_id])
        env = {'ROS_DOMAIN_ID': str(self.domains[robot_id]), 'ROS_HOME': str(home)}
        robot = [find_executable(*ROBOT_EXECUTABLE)]
        if self.robot_args:
            robot += ['--ros-args', *(arg for p in self.robot_args for arg in ('-p', p))]
        self.start_child(f'{robot_id}/sim_robot', robot, ROBOT_READY, env)
        task_manager = [find_executable(*TASK_MANAGER_EXECUTABLE), '--ros-args', '--params-file']
        self.start_child(
            f'{robot_id}/task_manager',
            [*task_manager, str(self.params_file)],
            TASK_MANAGER_READY,
            env,
        )
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
                '          (each robot has an account of its own, see '
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
                '',
                'In a second terminal, send a mission to every robot and watch the fleet:',
                f'  {python} {EXAMPLE} --broker-url {url} \\',
                f'      --password-file {password_file}',
                '',
                'Ctrl-C stops the broker, the robots, their Task Managers and bridges.',
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


def parse_arguments(argv: list[str] | None) -> argparse.Namespace:
    ros_home = Path(os.environ.get('ROS_HOME') or Path.home() / '.ros')
    parser = argparse.ArgumentParser(prog='task-manager-fleet', description=__doc__)
    parser.add_argument('--robots', type=int, default=DEFAULT_ROBOTS, help='how many (3)')
    parser.add_argument(
        '--broker-port', type=int, default=DEFAULT_PORT, help='default 0: any free one'
    )
    parser.add_argument(
        '--first-domain',
        type=int,
        default=DEFAULT_FIRST_DOMAIN,
        help='ROS domain of robot1; robot2 gets the next, ... (1)',
    )
    parser.add_argument(
        '--folder',
        type=Path,
        default=ros_home / 'task_manager' / 'fleet',
        help="broker files and each robot's ROS_HOME ($ROS_HOME/task_manager/fleet)",
    )
    parser.add_argument(
        '--robot-arg',
        action='append',
        metavar='NAME:=VALUE',
        help='a ROS parameter of every simulated robot (e.g. linear_speed:=4.0)',
    )
    parser.add_argument('--ready-timeout', type=float, default=READY_TIMEOUT_SEC)
    options = parser.parse_args(argv)
    if options.robots < 1:
        parser.error('--robots: at least 1')
    return options


def main(argv: list[str] | None = None) -> int:
    options = parse_arguments(argv)
    use_quick_discovery()  # also for the children, which inherit the environment
    return supervise(
        lambda events: Fleet(options, events),
        options.ready_timeout,
        'task-manager-fleet: the fleet has stopped',
    )


if __name__ == '__main__':
    sys.exit(main())
