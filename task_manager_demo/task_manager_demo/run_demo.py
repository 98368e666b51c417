"""Console script `task-manager-demo`: the simulated robot and the Task Manager, ready to use.

Starts the robot, the Task Manager and its web gateway (dashboard) as child processes, waits
(bounded) until each logs that it is ready, then prints what to try next and streams their
logs. Ctrl-C, SIGTERM or SIGHUP (the terminal closed) stops them all (SIGINT, a bounded wait,
a kill only as a last resort) and exits 0. A child that dies first fails the demo. If the
launcher itself is killed, its children get SIGTERM.
"""

import argparse
import os
import re
import secrets
import shutil
import sys
import textwrap
from collections.abc import Sequence
from pathlib import Path

from task_manager.discovery import use_quick_discovery
from task_manager_demo.children import Events
from task_manager_demo.robot_interface import ROBOT_READY_LOG
from task_manager_demo.supervisor import Supervisor, say, supervise

PACKAGE = 'task_manager_demo'
PARAMS_NAME = 'demo_tasks.yaml'
ROBOT_EXECUTABLE = ('task-manager-demo-robot', PACKAGE)
TASK_MANAGER_EXECUTABLE = ('task-manager', 'task_manager')
WEB_EXECUTABLE = ('task-manager-web', 'task_manager_web')
WEB_READY = re.compile(r'dashboard: (?P<dashboard>http://\S+)')
WEB_ADMIN_TOKEN_VARIABLE = 'TASK_MANAGER_WEB_ADMIN_TOKEN'
"""task-manager-web's admin token when it has no token file (docs/web.md)."""
DEFAULT_WEB_PORT = 8080
TASK_MANAGER_READY = re.compile(r'Task Manager ready with \d+ task\(s\): (?P<tasks>.*)$')
ROBOT_READY = re.compile(re.escape(ROBOT_READY_LOG) + r' at (?P<pose>\([^)]*\))')
READY_TIMEOUT_SEC = 30.0
EXIT_USAGE = 2
RULE = '=' * 78


def default_params_file() -> Path:
    """demo_tasks.yaml beside the package sources (editable install), or in its share folder."""
    source = Path(__file__).resolve().parents[1] / 'params' / PARAMS_NAME
    if source.exists():
        return source
    from ament_index_python.packages import get_package_share_directory

    return Path(get_package_share_directory(PACKAGE)) / 'params' / PARAMS_NAME


def find_executable(name: str, package: str) -> str:
    """A console script beside this interpreter, on PATH, or where colcon installs it."""
    beside_python = Path(sys.executable).with_name(name)
    if beside_python.exists():
        return str(beside_python)
    on_path = shutil.which(name)
    if on_path:
        return on_path
    from ament_index_python.packages import get_package_prefix

    return str(Path(get_package_prefix(package)) / 'lib' / package / name)


def shown_path(path: Path) -> str:
    """`path` relative to the working directory when it lies below it, else absolute."""
    absolute = os.path.abspath(path)
    relative = os.path.relpath(absolute)
    return absolute if relative.startswith('..') else relative


def start_robot(
    supervisor: Supervisor,
    params_file: Path,
    prefix: str = '',
    env: dict[str, str] | None = None,
    robot_parameters: Sequence[str] = (),
) -> None:
    """The simulated robot (with these `NAME:=VALUE` ROS parameters) and a Task Manager of
    `params_file`, children of `supervisor` named `<prefix>sim_robot` and
    `<prefix>task_manager`, with `env` added to their environment."""
    robot = [find_executable(*ROBOT_EXECUTABLE)]
    if robot_parameters:
        robot += ['--ros-args', *(arg for p in robot_parameters for arg in ('-p', p))]
    supervisor.start_child(f'{prefix}sim_robot', robot, ROBOT_READY, env)
    task_manager = [find_executable(*TASK_MANAGER_EXECUTABLE), '--ros-args', '--params-file']
    supervisor.start_child(
        f'{prefix}task_manager', [*task_manager, str(params_file)], TASK_MANAGER_READY, env
    )


def banner(tasks: str, robot_pose: str, params_file: Path, dashboard: str = '') -> str:
    taskctl = shown_path(Path(sys.executable).with_name('taskctl'))
    return '\n'.join(
        [
            RULE,
            f'Task Manager ready, with a simulated robot at {robot_pose}',
            textwrap.fill(
                f'{tasks} and the system/ tasks',
                width=len(RULE),
                initial_indent='  tasks:  ',
                subsequent_indent=' ' * 10,
                break_on_hyphens=False,
            ),
            f'  params: {shown_path(params_file)}',
            *([f'  dashboard: {dashboard}'] if dashboard else []),
            '  watch:  /task_manager/active_tasks  tasks in progress',
            '          /task_manager/results       one result per task',
            '',
            'In a second terminal, try:',
            f'  {taskctl} start navigation/navigate_to_pose \'{{"x": 2.0, "y": 1.0}}\'',
            f'  {taskctl} active --watch',
            f'  {taskctl} mission examples/mission.yaml',
            '',
            'Ctrl-C stops the robot, the Task Manager and the dashboard.',
            RULE,
        ]
    )


class Demo(Supervisor):
    """The robot, the Task Manager and (unless web_port is None) the web gateway."""

    def __init__(
        self,
        params_file: Path,
        events: Events,
        web_port: int | None,
        token_file: Path | None = None,
    ) -> None:
        """`web_port`: where the web gateway listens (0: any free port); None: no gateway.
        `token_file`: the gateway's tokens and their roles; None: one admin token, made."""
        super().__init__(events)
        self.params_file = params_file
        self.web_port = web_port
        self.token_file = token_file
        self.admin_token = secrets.token_urlsafe(24)
        """The gateway's admin token without a token file: made here, so that a gateway
        started again (exit 3) keeps the one the dashboard was opened with."""

    def start(self) -> None:
        start_robot(self, self.params_file)
        if self.web_port is not None:
            web = [find_executable(*WEB_EXECUTABLE), '--port', str(self.web_port)]
            if self.token_file is not None:
                web += ['--token-file', str(self.token_file)]
            env = {WEB_ADMIN_TOKEN_VARIABLE: self.admin_token} if self.token_file is None else {}
            self.start_child('web', web, WEB_READY, env=env)

    def banner(self, ready: dict[str, str]) -> str:
        return banner(ready['tasks'], ready['pose'], self.params_file, ready.get('dashboard', ''))


def parse_arguments(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog='task-manager-demo', description=__doc__)
    parser.add_argument(
        '--params-file', type=Path, help=f'Task Manager parameters (default: {PARAMS_NAME})'
    )
    parser.add_argument(
        '--ready-timeout',
        type=float,
        default=READY_TIMEOUT_SEC,
        help='seconds the processes may take to be ready (default: %(default)s)',
    )
    parser.add_argument(
        '--web-port',
        type=int,
        default=DEFAULT_WEB_PORT,
        help='port of the dashboard and web API, 0: any free one (default: %(default)s)',
    )
    parser.add_argument('--no-web', action='store_true', help='no web gateway')
    parser.add_argument(
        '--token-file',
        type=Path,
        help="the web gateway's tokens, one 'ROLE TOKEN [NAME]' line each (default: one admin "
        'token, made and printed)',
    )
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    options = parse_arguments(argv)
    use_quick_discovery()  # also for the children, which inherit the environment
    params_file = (options.params_file or default_params_file()).resolve()
    if not params_file.is_file():
        say(f'task-manager-demo: no parameters file {params_file}')
        return EXIT_USAGE
    web_port = None if options.no_web else options.web_port
    token_file = options.token_file.resolve() if options.token_file else None
    return supervise(
        lambda events: Demo(params_file, events, web_port, token_file),
        options.ready_timeout,
        'task-manager-demo: the robot and the Task Manager have stopped',
    )


if __name__ == '__main__':
    sys.exit(main())
