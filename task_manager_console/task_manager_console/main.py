"""Console script `task-manager-console`: every robot on an MQTT broker, and the fleet history.

It follows every robot under the prefix (its connection, declared and active tasks, schedules)
and stores each robot's results exactly once in the fleet history: a SQLite file by default
($ROS_HOME/task_manager/console/fleet.sqlite), PostgreSQL with
`--database postgresql://user@host[:port]/database`. Give the console an account of its own on
the broker (one account holds one connection), its password in `--password-file`.

Ctrl-C or SIGTERM: a clean stop; the broker keeps the console's session, and the results sent
meanwhile, until it is back. Exit codes: 0 after a clean stop, 2 for unusable settings, a
database or a broker that cannot be reached at the start.
"""

import argparse
import logging
import signal
import sys
import threading
from pathlib import Path

from task_manager_mqtt.fleet_types import FleetError
from task_manager_mqtt.settings import DEFAULT_PREFIX, Broker, SettingsError
from task_manager_web.doors.settings import add_door_arguments

from task_manager_console.app import serve, settings_of
from task_manager_console.fleet import CONSOLE_CLIENT_ID, Fleet
from task_manager_console.store.fleet_history import DatabaseUnavailable, FleetHistory
from task_manager_console.store.location import default_database_url

EXIT_USAGE = 2
BROKER_TIMEOUT_SEC = 10.0
"""How long the start waits for the broker."""
DEFAULT_BROKER_URL = 'mqtt://127.0.0.1:1883'
DEFAULT_PORT = 8090
LOG_FORMAT = 'task-manager-console: [%(levelname)s] %(message)s'
LOG = logging.getLogger('task_manager_console')
READY_LINE = 'following the robots under'


def _arguments(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog='task-manager-console',
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        '--broker-url',
        default=DEFAULT_BROKER_URL,
        help='mqtt://[user[:password]@]host[:port] or mqtts://... (TLS); %(default)s',
    )
    parser.add_argument('--password-file', type=Path, help='file holding the broker password')
    parser.add_argument('--ca-file', default='', help='TLS: certificate authorities to trust')
    parser.add_argument('--prefix', default=DEFAULT_PREFIX, help='topic prefix (%(default)s)')
    parser.add_argument(
        '--client-id',
        default=CONSOLE_CLIENT_ID,
        help='MQTT client id, kept by the broker with its session (%(default)s); a broker that '
        "ties ids to accounts uses the account's name",
    )
    parser.add_argument(
        '--database',
        default='',
        help='sqlite:///path or postgresql://user@host[:port]/database '
        '(sqlite:///$ROS_HOME/task_manager/console/fleet.sqlite)',
    )
    parser.add_argument('--host', default='127.0.0.1', help='address of the doors (%(default)s)')
    parser.add_argument('--port', type=int, default=DEFAULT_PORT, help='their port (%(default)s)')
    add_door_arguments(parser, "the console's name")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    logging.basicConfig(level=logging.INFO, format=LOG_FORMAT, stream=sys.stderr)
    arguments = _arguments(argv)
    try:
        broker = Broker.from_url(arguments.broker_url)
        if arguments.password_file is not None:
            broker = broker.with_password_file(arguments.password_file, LOG)
    except SettingsError as error:
        print(f'task-manager-console: {error}', file=sys.stderr)
        return EXIT_USAGE
    try:
        settings = settings_of(arguments)
    except SystemExit as error:  # a token file that cannot be read: one line
        print(error, file=sys.stderr)
        return EXIT_USAGE
    try:
        history = FleetHistory.open(arguments.database or default_database_url())
    except DatabaseUnavailable as error:
        print(f'task-manager-console: {error}', file=sys.stderr)
        return EXIT_USAGE
    stop = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    fleet = Fleet(
        arguments.broker_url,
        history,
        prefix=arguments.prefix,
        client_id=arguments.client_id,
        password=broker.password,
        ca_file=arguments.ca_file,
    )
    try:
        fleet.start(BROKER_TIMEOUT_SEC)
    except FleetError as error:
        print(f'task-manager-console: {error}', file=sys.stderr)
        history.close()
        return EXIT_USAGE
    LOG.info(
        '%s %s/ on %s; fleet history: %s',
        READY_LINE,
        arguments.prefix,
        broker.url,
        history.url,
    )
    try:
        serve(fleet, settings, stop)
    except SystemExit as error:  # the doors cannot listen: one line
        print(error, file=sys.stderr)
        return EXIT_USAGE
    finally:
        fleet.close()
        history.close()
    return 0


if __name__ == '__main__':
    sys.exit(main())
