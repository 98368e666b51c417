"""Console script `task-manager-mqtt`: one robot's Task Manager on an MQTT broker.

Settings come from the options, or from a YAML file (`--config`) of the same names with `_`
for `-` (options given on the command line win), e.g.:

    robot_id: robot1
    broker_url: mqtts://robot1@broker.example.com
    password_file: /etc/task_manager/mqtt_password
    tls: {ca_file: /etc/ssl/certs/broker-ca.pem}

Ctrl-C or SIGTERM: OFFLINE is published (retained), then a clean disconnection. Exit codes:
0 after a clean stop, 2 for unusable settings or credentials the broker refuses, 3 when, held
up, it no longer hears its Task Manager (start it again: its supervisor's work).
"""

import argparse
import logging
import signal
import sys
import threading
from dataclasses import replace
from pathlib import Path
from typing import Any

from task_manager.client import TaskManagerClient
from task_manager.cpu_priority import GATEWAY_NICENESS, add_nice_argument, lower_cpu_priority
from task_manager.process_setup import (
    EXIT_NODE_UNHEARD,
    end_within,
    prepare_ros_process,
    stop_when_unheard,
)
from task_manager_mqtt.bridge import Bridge
from task_manager_mqtt.settings import (
    DEFAULT_MAX_PAYLOAD_BYTES,
    DEFAULT_PREFIX,
    BridgeSettings,
    Broker,
    SettingsError,
    Tls,
    read_yaml,
    tls_from,
)

EXIT_USAGE = 2
CLIENT_TIMEOUT_SEC = 5.0
DEFAULTS: dict[str, Any] = {
    'broker_url': 'mqtt://127.0.0.1:1883',
    'prefix': DEFAULT_PREFIX,
    'source': 'CLOUD',
    'max_payload_bytes': DEFAULT_MAX_PAYLOAD_BYTES,
    'keepalive_sec': 10,
    'reconnect_max_sec': 2,
    'nice': GATEWAY_NICENESS,
}
LOG_FORMAT = 'task-manager-mqtt: [%(levelname)s] %(message)s'
LOG = logging.getLogger('task_manager_mqtt')


def _arguments(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog='task-manager-mqtt',
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        argument_default=argparse.SUPPRESS,  # unset options leave the file's value
    )
    parser.add_argument('--config', type=Path, help='YAML settings file')
    parser.add_argument('--robot-id', help="this robot's id: one topic level (required)")
    parser.add_argument(
        '--broker-url', help='mqtt://[user[:password]@]host[:port] or mqtts://... (TLS)'
    )
    parser.add_argument('--password-file', type=Path, help='file holding the broker password')
    parser.add_argument('--ca-file', help='TLS: certificate authorities to trust')
    parser.add_argument('--prefix', help=f'topic prefix ({DEFAULT_PREFIX})')
    parser.add_argument('--source', help='source of the tasks the cloud starts (CLOUD)')
    parser.add_argument(
        '--state-file',
        type=Path,
        help='where the last acknowledged result is kept '
        '($ROS_HOME/task_manager/mqtt/<robot_id>.acked)',
    )
    parser.add_argument(
        '--max-payload-bytes',
        type=int,
        help="largest request accepted and message sent (1 MiB): the broker's message size limit",
    )
    parser.add_argument('--keepalive-sec', type=int, help='MQTT keep-alive (10 s)')
    parser.add_argument(
        '--reconnect-max-sec', type=int, help='longest wait between connection attempts (2 s)'
    )
    add_nice_argument(parser, default=None)  # the file's, else DEFAULTS'
    return parser.parse_args(argv)


def settings_from(options: dict[str, Any]) -> BridgeSettings:
    """BridgeSettings from the file's values overridden by the options; SettingsError if bad."""
    values = {**DEFAULTS}
    if options.get('config') is not None:
        values.update(read_yaml(options['config']))
    values.update({k: v for k, v in options.items() if k != 'config'})
    known = {*DEFAULTS, 'robot_id', 'password_file', 'ca_file', 'tls', 'state_file'}
    unknown = sorted(set(values) - known)
    if unknown:
        raise SettingsError(f'unknown settings {unknown}; allowed: {sorted(known)}')
    if not values.get('robot_id'):
        raise SettingsError('robot_id is required (--robot-id or robot_id: in --config)')
    tls = tls_from(values)
    if values.get('ca_file'):
        tls = replace(tls or Tls(), ca_file=str(values['ca_file']))
    broker = Broker.from_url(str(values['broker_url']), tls)
    if values.get('password_file'):
        broker = broker.with_password_file(Path(values['password_file']), LOG)
    state_file = values.get('state_file')
    return BridgeSettings(
        robot_id=str(values['robot_id']),
        broker=broker,
        prefix=str(values['prefix']),
        source=str(values['source']),
        state_file=None if state_file is None else Path(state_file),
        max_payload_bytes=int(values['max_payload_bytes']),
        keepalive_sec=int(values['keepalive_sec']),
        reconnect_max_sec=int(values['reconnect_max_sec']),
        nice=values['nice'],
    )


def main(argv: list[str] | None = None) -> int:
    prepare_ros_process()
    logging.basicConfig(level=logging.INFO, format=LOG_FORMAT, stream=sys.stderr)
    try:
        settings = settings_from(vars(_arguments(argv)))
    except SettingsError as error:
        print(f'task-manager-mqtt: {error}', file=sys.stderr)
        return EXIT_USAGE
    lower_cpu_priority(settings.nice)
    stop = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    client = TaskManagerClient('task_manager_mqtt', timeout_sec=CLIENT_TIMEOUT_SEC)
    code = 1  # an error of ours, raised on
    try:
        bridge = Bridge(settings, client, on_failure=stop.set)
        unheard = stop_when_unheard(client, stop.set)
        bridge.start()
        stop.wait()
        bridge.stop()
        code = EXIT_NODE_UNHEARD if unheard.is_set() else 0
        if bridge.failed.is_set():
            LOG.error(bridge.failure)
            code = EXIT_USAGE
    finally:
        end_within(client.close, 'task-manager-mqtt', code)
    return code


if __name__ == '__main__':
    sys.exit(main())
