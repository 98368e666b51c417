"""`make vda5050`: the demo robot as a VDA 5050 vehicle on a local broker.

Starts a local mosquitto (an account for the vehicle and one for a master control, each
limited to its side of the standard's topics), the simulated robot, a Task Manager with the
demo's tasks and the VDA 5050 adapter with the demo's mapping. Once all are ready it prints
the broker URL a master control connects with (with its password: a local demo broker) and
the vehicle's topic prefix, then streams their logs. Ctrl-C stops everything it started.
"""

import argparse
import re
import sys
from pathlib import Path

from task_manager_vda5050.broker import MASTER_USER, VdaBroker
from task_manager_vda5050.mapping import DEMO_MAPPING
from task_manager_vda5050.topics import DEFAULT_INTERFACE

from task_manager_demo.children import Events
from task_manager_demo.run_demo import (
    default_params_file,
    find_executable,
    shown_path,
    start_robot,
)
from task_manager_demo.run_fleet import (
    BROKER_READY,
    PASSWORD_FILE,
    RULE,
    broker_demo_parser,
    write_password,
)
from task_manager_demo.supervisor import Supervisor, supervise_demo

ADAPTER_EXECUTABLE = ('task-manager-vda5050', 'task_manager_vda5050')
ADAPTER_READY = re.compile(r'connected to the broker')
MANUFACTURER = 'demo'
SERIAL_NUMBER = 'robot1'
EXAMPLE = Path('examples') / 'vda5050_order.py'


class VdaDemo(Supervisor):
    def __init__(self, options: argparse.Namespace, events: Events) -> None:
        super().__init__(events, prefix_lines=True)
        self.folder: Path = options.folder
        self.broker = VdaBroker(
            self.folder / 'broker', MANUFACTURER, [SERIAL_NUMBER], port=options.broker_port
        )

    def start(self) -> None:
        self.start_child('broker', self.broker.command, BROKER_READY)
        start_robot(self, default_params_file())
        password_file = self.folder / SERIAL_NUMBER / PASSWORD_FILE
        write_password(password_file, self.broker.passwords[SERIAL_NUMBER])
        adapter = [
            find_executable(*ADAPTER_EXECUTABLE),
            '--manufacturer',
            MANUFACTURER,
            '--serial-number',
            SERIAL_NUMBER,
            '--broker-url',
            f'mqtt://{SERIAL_NUMBER}@127.0.0.1:{self.broker.port}',
            '--password-file',
            str(password_file),
            '--mapping',
            str(DEMO_MAPPING),
        ]
        self.start_child('vda5050', adapter, ADAPTER_READY)

    def banner(self, ready: dict[str, str]) -> str:
        url = self.broker.url(MASTER_USER)
        python = shown_path(Path(sys.executable))
        return '\n'.join(
            [
                RULE,
                'VDA 5050 vehicle ready: the simulated robot, its Task Manager and the adapter',
                f'  broker: {url}',
                f'  vda5050: {DEFAULT_INTERFACE}/v2/{MANUFACTURER}/{SERIAL_NUMBER}',
                '           (order, instantActions in; state, connection, factsheet, '
                'visualization out)',
                f'  mapping: {shown_path(DEMO_MAPPING)}',
                '',
                'In a second terminal, send an order with a photo and watch its progress:',
                f'  {python} {EXAMPLE} --broker-url {url}',
                '',
                'Ctrl-C stops the broker, the robot, its Task Manager and the adapter.',
                RULE,
            ]
        )


def parse_arguments(argv: list[str] | None) -> argparse.Namespace:
    parser = broker_demo_parser(
        'run_vda5050', __doc__, 'vda5050', 'broker files and the password file'
    )
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    return supervise_demo(VdaDemo, parse_arguments(argv), 'make vda5050: everything has stopped')


if __name__ == '__main__':
    sys.exit(main())
