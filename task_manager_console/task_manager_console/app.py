"""The console's doors: its REST API, event stream, metrics and page (a FastAPI application on a
Fleet), and `serve`, which runs them until the console stops.

They follow the web gateway's conventions with its own code (task_manager_web: the token file
and roles, who may do what by effect, the error documents, the security headers, the Host
allow-list, the body's and the reads' bounds, the HTTP server). Before routing, a request
passes the same doors (`task_manager_web.doors.settings.add_doors`).
"""

import argparse
import asyncio
import contextlib
import threading
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import task_manager_web.doors.access
from fastapi import FastAPI, Request, Response
from fastapi.responses import FileResponse
from fastapi.staticfiles import StaticFiles
from task_manager_web.door_link import end_event_streams
from task_manager_web.doors.access import Access, MetricsViewer
from task_manager_web.doors.settings import (
    DoorSettings,
    add_doors,
    add_whoami,
    allowed_hosts,
    door_app,
)
from task_manager_web.doors.tokens import dashboard_line, door_tokens
from task_manager_web.errors import ApiError
from task_manager_web.http_server import HEADER_TIMEOUT_SEC, Server, listen, server_config
from task_manager_web.request_metrics import METRICS_ROUTE, metrics_response

from task_manager.protocol.errors import RefusalCode
from task_manager_console.console_metrics import ConsoleMetrics
from task_manager_console.fleet import Fleet
from task_manager_console.fleet_link import FleetLink, Link
from task_manager_console.fleet_routes import add_fleet_routes
from task_manager_console.robot_routes import add_robot_routes

PROGRAM = 'task-manager-console'
STATIC = Path(__file__).with_name('static')
# The robot dashboard's files the page shares, found from a module of the web gateway (its
# doors/ is beside static/; not by the package's name: a worker started with `python -c` has
# its current folder first on sys.path, where the colcon folder task_manager_web/ passes for a
# namespace package).
WEB_STATIC = Path(task_manager_web.doors.access.__file__).parents[1] / 'static'
SOURCE = 'CLOUD'
"""The door of what the console starts, as the bridges stamp it (`CLOUD:<token name>`)."""
READ_PATHS = ('/api/robots', '/api/history')
"""The reads bounded per client (GET of each, and what is under it)."""


@dataclass(frozen=True)
class Settings(DoorSettings):
    """The doors' settings (the console's command line gives them)."""

    host: str = '127.0.0.1'
    port: int = 0
    token_file: Path | None = None
    """Where the tokens come from (None: one made at the start, printed)."""
    header_timeout_sec: float = HEADER_TIMEOUT_SEC
    access_log: bool = False


def settings_of(arguments: argparse.Namespace) -> Settings:
    """The doors' settings from the command line; SystemExit (one line) for a token file that
    cannot be read."""
    return Settings(
        tokens=door_tokens(PROGRAM, arguments.token_file),
        host=arguments.host,
        port=arguments.port,
        token_file=arguments.token_file,
        allowed_hosts=allowed_hosts(arguments),
        metrics_without_token=arguments.metrics_without_token,
        max_history_bytes=arguments.max_history_bytes,
        access_log=arguments.access_log,
    )


def create_app(fleet: Fleet, settings: Settings) -> FastAPI:
    """The doors of `fleet` (started, or started by whoever runs them)."""

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        app.state.link = FleetLink(fleet, asyncio.get_running_loop())
        try:
            yield
        finally:
            app.state.link.close()
            metrics.close()

    app = door_app(
        'Task Manager fleet console',
        "Every robot's tasks on an MQTT broker, and the fleet history.",
        lifespan,
    )
    access = Access(
        settings.tokens, source=SOURCE, metrics_without_token=settings.metrics_without_token
    )
    metrics = ConsoleMetrics(fleet)
    app.state.metrics = metrics
    add_doors(app, settings, access, metrics.request_counts, READ_PATHS)
    add_whoami(app)
    _add_routes(app)
    add_robot_routes(app)
    add_fleet_routes(app)
    # the page's files (the folder may be absent: then / answers 404)
    app.mount('/static', StaticFiles(directory=str(STATIC), check_dir=False), name='static')
    # the robot dashboard's helpers and style sheet, which the page shares
    app.mount('/web-static', StaticFiles(directory=str(WEB_STATIC)), name='web')
    return app


def _add_routes(app: FastAPI) -> None:
    @app.get('/', include_in_schema=False)
    async def page() -> FileResponse:
        index = STATIC / 'index.html'
        if not index.is_file():
            raise ApiError(404, RefusalCode.NOT_FOUND, 'this console has no page')
        return FileResponse(str(index))

    @app.get('/api/health', tags=['state'])
    async def health(link: Link) -> dict[str, Any]:
        """Whether the fleet history stores, how many robots are seen and ONLINE, how many
        results wait to be stored (no token needed)."""
        robots = link.fleet.robots.values()
        return {
            'database_up': link.fleet.database_up,
            'robots': len(robots),
            'online': sum(1 for robot in robots if robot.online),
            'results_waiting': link.fleet.results_waiting(),
            'event_streams': link.stream_count,
        }

    @app.get('/metrics', **METRICS_ROUTE)
    async def metrics(_: MetricsViewer, request: Request) -> Response:
        """Prometheus metrics (text format): each robot's connection, active, queued and
        paused tasks, results stored and bad messages; the tasks ended by robot and status;
        the fleet history's; this console's requests. Needs a token unless
        --metrics-without-token."""
        console_metrics: ConsoleMetrics = request.app.state.metrics
        return metrics_response(console_metrics.registry)


def serve(fleet: Fleet, settings: Settings, stop: threading.Event) -> None:
    """Serve the doors of `fleet` until `stop` is set, or SIGINT or SIGTERM comes (then `stop`
    is set too); prints the page's link (`dashboard: http://HOST:PORT/?token=TOKEN` with the
    token made here, as the web gateway does) once it listens. SystemExit (one line) when it
    cannot listen."""
    listener = listen(PROGRAM, settings.host, settings.port)
    app = create_app(fleet, settings)
    server = Server(
        server_config(app, settings.header_timeout_sec, settings.access_log),
        lambda: end_event_streams(app, 'the console stops'),
    )
    host, port = listener.getsockname()[:2]
    shown_host = f'[{host}]' if ':' in host else host
    url = f'http://{shown_host}:{port}/'
    print(dashboard_line(url, settings.tokens, settings.token_file), flush=True)

    async def run() -> None:
        loop = asyncio.get_running_loop()

        def on_stop() -> None:
            stop.wait()
            with contextlib.suppress(RuntimeError):  # the loop ended first
                loop.call_soon_threadsafe(setattr, server, 'should_exit', True)

        threading.Thread(target=on_stop, name='console-stop', daemon=True).start()
        await server.serve(sockets=[listener])

    try:
        asyncio.run(run())
    finally:
        stop.set()
        listener.close()
