"""Console script `task-manager-vda5050`: one robot's Task Manager as a VDA 5050 vehicle.

    task-manager-vda5050 --manufacturer acme --serial-number robot1 \\
        --broker-url mqtt://robot1@127.0.0.1:1883 --password-file pw --mapping mapping.yaml

It waits for the Task Manager, then connects to the broker (last will CONNECTIONBROKEN,
then ONLINE, both retained) and serves <interface>/v2/<manufacturer>/<serialNumber>/order
and instantActions. Ctrl-C or SIGTERM: OFFLINE is published (retained), then a clean
disconnection. Exit codes: 0 after a clean stop, 2 for unusable settings, a mapping that
cannot be read or credentials the broker refuses, 3 when no Task Manager answered within 30 s
or, held up, it no longer hears its Task Manager (start it again: its supervisor's work).
"""

import argparse
import logging
import signal
import sys
import threading
import time
from pathlib import Path
from typing import Any

from task_manager_mqtt.settings import Broker, SettingsError

from task_manager.client import TaskManagerClient
from task_manager.core.errors import TaskManagerError, TaskManagerUnavailable
from task_manager.cpu_priority import GATEWAY_NICENESS, add_nice_argument, lower_cpu_priority
from task_manager.process_setup import (
    EXIT_NODE_UNHEARD,
    EXIT_START_AGAIN,
    end_within,
    prepare_ros_process,
    stop_when_unheard,
)
from task_manager_vda5050.adapter import STATE_PERIOD_SEC, Adapter
from task_manager_vda5050.link import Link
from task_manager_vda5050.mapping import Mapping, MappingError, read_mapping
from task_manager_vda5050.topics import DEFAULT_INTERFACE, Vehicle

EXIT_USAGE = 2
CLIENT_TIMEOUT_SEC = 5.0
TASK_MANAGER_WAIT_SEC = 30.0
LOG_FORMAT = 'task-manager-vda5050: [%(levelname)s] %(message)s'
LOG = logging.getLogger('task_manager_vda5050')


def _arguments(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog='task-manager-vda5050',
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument('--manufacturer', required=True, help='one topic level')
    parser.add_argument('--serial-number', required=True, help='one topic level')
    parser.add_argument('--interface-name', default=DEFAULT_INTERFACE, help='(uagv)')
    parser.add_argument('--mapping', type=Path, required=True, help='YAML mapping to tasks')
    parser.add_argument(
        '--broker-url',
        default='mqtt://127.0.0.1:1883',
        help='mqtt://[user[:password]@]host[:port] or mqtts://... (TLS)',
    )
    parser.add_argument('--password-file', type=Path, help='file holding the broker password')
    parser.add_argument(
        '--state-period-sec', type=float, default=STATE_PERIOD_SEC, help='state at least every (30)'
    )
    parser.add_argument('--keepalive-sec', type=int, default=10, help='MQTT keep-alive (10 s)')
    add_nice_argument(parser, default=GATEWAY_NICENESS)
    return parser.parse_args(argv)


def _broker(options: argparse.Namespace) -> Broker:
    broker = Broker.from_url(options.broker_url)
    if options.password_file is None:
        return broker
    return broker.with_password_file(options.password_file, LOG)


def main(argv: list[str] | None = None) -> int:
    prepare_ros_process()
    logging.basicConfig(level=logging.INFO, format=LOG_FORMAT, stream=sys.stderr)
    options = _arguments(argv)
    lower_cpu_priority(options.nice)
    try:
        vehicle = Vehicle(options.manufacturer, options.serial_number, options.interface_name)
        broker = _broker(options)
        mapping = read_mapping(options.mapping)
    except (SettingsError, MappingError, ValueError) as error:
        print(f'task-manager-vda5050: {error}', file=sys.stderr)
        return EXIT_USAGE
    stop = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    client = TaskManagerClient('task_manager_vda5050', timeout_sec=CLIENT_TIMEOUT_SEC)
    code = 1  # an error of ours, raised on
    try:
        try:
            deadline = time.monotonic() + TASK_MANAGER_WAIT_SEC
            client.wait_until_available(TASK_MANAGER_WAIT_SEC, events=True)
            declared = _declared_tasks(client, deadline)
        except TaskManagerError as error:
            print(f'task-manager-vda5050: {error}', file=sys.stderr)
            # none within the wait, or not all of it (a newcomer's participant now and then
            # never meets some of the node's endpoints): a new process may
            unavailable = isinstance(error, TaskManagerUnavailable)
            code = EXIT_START_AGAIN if unavailable else EXIT_USAGE
        else:
            code = _serve(client, declared, vehicle, broker, mapping, options, stop)
    finally:
        end_within(client.close, 'task-manager-vda5050', code)
    return code


def _declared_tasks(client: TaskManagerClient, deadline: float) -> list[dict[str, Any]]:
    """The node's declared tasks, asked again until `deadline` (time.monotonic): a newcomer can
    find the node's parameter services some seconds after its action and event stream (seen:
    more than the client's 5 s on a loaded machine)."""
    while True:
        try:
            return client.declared_tasks()
        except TaskManagerUnavailable:
            if time.monotonic() >= deadline:
                raise


def _serve(
    client: TaskManagerClient,
    declared: list[dict[str, Any]],
    vehicle: Vehicle,
    broker: Broker,
    mapping: Mapping,
    options: argparse.Namespace,
    stop: threading.Event,
) -> int:
    link = Link(vehicle, broker, keepalive_sec=options.keepalive_sec)
    adapter = Adapter(client, declared, link, mapping, options.state_period_sec)
    link.on_message = adapter.on_message
    link.on_connected = adapter.on_connected
    unheard = stop_when_unheard(client, stop.set)
    adapter.start()
    link.start()
    threading.Thread(target=_stop_when_refused, args=(link, stop), daemon=True).start()
    stop.wait()
    link.stop()
    adapter.stop()
    if unheard.is_set():
        return EXIT_NODE_UNHEARD
    return EXIT_USAGE if link.refused.is_set() else 0


def _stop_when_refused(link: Link, stop: threading.Event) -> None:
    """Credentials the broker refuses: no retry helps, the adapter stops (exit code 2)."""
    link.refused.wait()
    stop.set()


if __name__ == '__main__':
    sys.exit(main())
