"""Console script `task-manager-web`: the web gateway of a running Task Manager.

Prints `dashboard: http://HOST:PORT/?token=TOKEN` once it listens, with the token it made
(an admin's) when it has no --token-file, whose tokens it never prints; Ctrl-C or SIGTERM
stops it. Exit codes: 0 after a clean stop, 2 for unusable settings, 3 when, held up, it no
longer hears its Task Manager (start it again: its supervisor's work).
"""

import argparse
import asyncio
import logging
import os
import sys
import threading

from task_manager.client import TaskManagerClient
from task_manager.cpu_priority import GATEWAY_NICENESS, add_nice_argument, lower_cpu_priority
from task_manager.process_setup import (
    EXIT_NODE_UNHEARD,
    end_within,
    prepare_ros_process,
    stop_when_unheard,
)
from task_manager_web.app import Settings, create_app
from task_manager_web.door_link import end_event_streams
from task_manager_web.doors.settings import (
    MAX_BODY_BYTES,
    MAX_READS_PER_CLIENT,
    add_door_arguments,
    allowed_hosts,
)
from task_manager_web.doors.tokens import dashboard_line, door_tokens
from task_manager_web.http_server import (
    HEADER_TIMEOUT_SEC,
    Server,
    listen,
    server_config,
    stopped_by_signals,
)

EXIT_USAGE = 2
DEFAULT_PORT = 8080
CLIENT_TIMEOUT_SEC = 5.0


def _arguments(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog='task-manager-web', description=__doc__)
    parser.add_argument('--host', default='127.0.0.1', help='address to listen on (127.0.0.1)')
    parser.add_argument(
        '--port', type=int, default=DEFAULT_PORT, help=f'0: any free port ({DEFAULT_PORT})'
    )
    parser.add_argument(
        '--read-without-token',
        action='store_true',
        help='let anyone read, as a viewer; the rest still needs a token',
    )
    parser.add_argument(
        '--source',
        default='WEB',
        help='source of the tasks started, cancelled and stopped here, followed by :NAME for a '
        'token with a name; requests cannot set it (WEB)',
    )
    parser.add_argument(
        '--max-body-bytes', type=int, default=MAX_BODY_BYTES, help='largest request body (1 MiB)'
    )
    parser.add_argument(
        '--max-reads-per-client',
        type=int,
        default=MAX_READS_PER_CLIENT,
        help='reads in flight per client (the token, or an address without it); more get 429 '
        f'({MAX_READS_PER_CLIENT})',
    )
    parser.add_argument(
        '--header-timeout-sec',
        type=float,
        default=HEADER_TIMEOUT_SEC,
        help="a request's head must arrive within this, else the connection is closed "
        f'({HEADER_TIMEOUT_SEC:g})',
    )
    add_door_arguments(parser, "e.g. the robot's name")
    add_nice_argument(parser, default=GATEWAY_NICENESS)
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> None:
    prepare_ros_process()
    arguments = _arguments(argv)
    lower_cpu_priority(arguments.nice)
    logging.basicConfig(
        level=logging.INFO, format='[%(levelname)s] [task_manager_web]: %(message)s'
    )
    try:
        tokens = door_tokens('task-manager-web', arguments.token_file, os.environ)
        listener = listen('task-manager-web', arguments.host, arguments.port)
    except SystemExit as error:
        print(error, file=sys.stderr)
        sys.exit(EXIT_USAGE)
    settings = Settings(
        tokens=tokens,
        read_without_token=arguments.read_without_token,
        metrics_without_token=arguments.metrics_without_token,
        source=arguments.source,
        max_body_bytes=arguments.max_body_bytes,
        max_reads_per_client=arguments.max_reads_per_client,
        max_history_bytes=arguments.max_history_bytes,
        allowed_hosts=allowed_hosts(arguments),
    )
    unheard: list[threading.Event] = []

    def make_client() -> TaskManagerClient:
        client = TaskManagerClient('task_manager_web', timeout_sec=CLIENT_TIMEOUT_SEC)
        unheard.append(stop_when_unheard(client, lambda: setattr(server, 'should_exit', True)))
        return client

    app = create_app(
        settings,
        make_client,
        lambda client: end_within(client.close, 'task-manager-web', 0),
    )
    config = server_config(app, arguments.header_timeout_sec, arguments.access_log)
    server = Server(config, lambda: end_event_streams(app, 'the gateway stops'))
    host, port = listener.getsockname()[:2]
    shown_host = f'[{host}]' if ':' in host else host
    dashboard = dashboard_line(f'http://{shown_host}:{port}/', tokens, arguments.token_file)
    # Ctrl-C is a clean stop from the first line printed on: before the server starts, it
    # starts and stops at once (the node's client made and closed)
    with stopped_by_signals(server):
        print(f'Task Manager web gateway on http://{shown_host}:{port}/ (API docs: /docs)')
        print(dashboard, flush=True)
        asyncio.run(server.serve(sockets=[listener]))
    if any(event.is_set() for event in unheard):
        sys.exit(EXIT_NODE_UNHEARD)


if __name__ == '__main__':
    main()
