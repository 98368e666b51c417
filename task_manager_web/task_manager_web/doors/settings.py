"""The doors as the web gateway and the fleet console both open them: their settings, the
command-line options that set them, and the middlewares every request passes before routing,
outermost first: FrontDoor (Host allow-list; the security headers of every answer),
RequestMetrics, ReadBound (reads in flight per client), BodyDoor (size, time and JSON of the
body). No rclpy here."""

import argparse
from collections.abc import Callable
from contextlib import AbstractAsyncContextManager
from dataclasses import dataclass
from pathlib import Path

from fastapi import FastAPI

from task_manager.core.bounds import HISTORY_PAGE_MAX_BYTES
from task_manager_web.doors.access import Access, Identity, Viewer
from task_manager_web.doors.body_door import BODY_TIMEOUT_SEC, BodyDoor
from task_manager_web.doors.front_door import LOCAL_HOSTS, FrontDoor
from task_manager_web.doors.read_bound import READ_PATHS, ReadBound
from task_manager_web.doors.tokens import Token
from task_manager_web.errors import add_error_handlers
from task_manager_web.request_metrics import RequestCounts, RequestMetrics

MAX_BODY_BYTES = 1_048_576
MAX_READS_PER_CLIENT = 32
"""The default bound of a client's reads in flight (the dashboard makes 3 at once)."""


@dataclass(frozen=True)
class DoorSettings:
    """What the doors let in, and how much."""

    tokens: tuple[Token, ...]
    """Who may come in, each token with its role (and maybe a name)."""
    allowed_hosts: tuple[str, ...] = LOCAL_HOSTS
    """The names a request's Host header may give (its port is not compared)."""
    metrics_without_token: bool = False
    """GET /metrics without a token (else it needs one, even where reading needs none)."""
    max_body_bytes: int = MAX_BODY_BYTES
    body_timeout_sec: float = BODY_TIMEOUT_SEC
    max_reads_per_client: int = MAX_READS_PER_CLIENT
    """Reads in flight per client (a token's holder, or an address without it); more: 429."""
    max_history_bytes: int = HISTORY_PAGE_MAX_BYTES
    """The largest history page answered (JSON or CSV); a larger one is refused."""


def add_door_arguments(parser: argparse.ArgumentParser, behind_proxy: str) -> None:
    """The options of the doors both programs take (`behind_proxy`: the name a Host header
    gives behind a reverse proxy, in --allowed-host's help)."""
    parser.add_argument(
        '--token-file',
        type=Path,
        help="file of the tokens, one 'ROLE TOKEN [NAME]' line each (ROLE: viewer, operator, "
        'admin); default: a new admin token, printed',
    )
    parser.add_argument(
        '--allowed-host',
        action='append',
        default=[],
        metavar='NAME',
        help='a name the Host header may give besides 127.0.0.1, localhost, ::1 and the --host '
        f'address ({behind_proxy} behind a reverse proxy); again for more',
    )
    parser.add_argument(
        '--metrics-without-token',
        action='store_true',
        help='let anyone read GET /metrics (a Prometheus scraper without a token)',
    )
    parser.add_argument(
        '--max-history-bytes',
        type=int,
        default=HISTORY_PAGE_MAX_BYTES,
        help='largest history page answered, JSON or CSV; a larger one is refused with '
        'reply_too_large (8 MiB)',
    )
    parser.add_argument(
        '--access-log',
        action='store_true',
        help='print a line per request (its token parameter removed)',
    )


def allowed_hosts(arguments: argparse.Namespace) -> tuple[str, ...]:
    """The Host names allowed: the local ones, --host's address and each --allowed-host."""
    return (*LOCAL_HOSTS, arguments.host, *arguments.allowed_host)


def door_app(
    title: str,
    summary: str,
    lifespan: Callable[[FastAPI], AbstractAsyncContextManager[None]],
) -> FastAPI:
    """A FastAPI application without FastAPI's own documentation pages (they load their
    scripts from a CDN: the web gateway serves Swagger UI itself, at /docs)."""
    return FastAPI(
        title=title,
        summary=summary,
        version='0.1.0',
        lifespan=lifespan,
        docs_url=None,
        redoc_url=None,
        swagger_ui_oauth2_redirect_url=None,
    )


def add_whoami(app: FastAPI) -> None:
    """GET /api/whoami: who the token sent is, for the page to offer what it may do."""

    @app.get('/api/whoami', tags=['state'])
    async def whoami(caller: Viewer) -> Identity:
        """The role and name of the token sent (a viewer without a name when reading needs
        no token and none is sent): what the page may offer."""
        return Identity.model_validate({'role': caller.role.label, 'name': caller.name})


def add_doors(
    app: FastAPI,
    settings: DoorSettings,
    access: Access,
    counts: RequestCounts,
    read_paths: tuple[str, ...] = READ_PATHS,
) -> None:
    """Put the doors before `app`'s routes, with `access` (app.state.access) for who comes in,
    `counts` for its requests and `read_paths` for the reads bounded per client; its errors
    answered as the protocol's error documents."""
    add_error_handlers(app)
    app.state.access = access
    app.state.max_history_bytes = settings.max_history_bytes
    # the last added is the outermost
    app.add_middleware(
        BodyDoor, max_bytes=settings.max_body_bytes, timeout_sec=settings.body_timeout_sec
    )
    app.add_middleware(
        ReadBound, access=access, max_reads=settings.max_reads_per_client, paths=read_paths
    )
    app.add_middleware(RequestMetrics, counts=counts)
    app.add_middleware(FrontDoor, allowed_hosts=settings.allowed_hosts)
