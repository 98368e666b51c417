"""The gateway's HTTP server: uvicorn's h11 server, with a deadline on each request's head and
an access log without tokens.

uvicorn's h11 server has no deadline for a request's head: 50 connections that sent half a
head each were held as long as their clients liked (the keep-alive timeout only runs between
requests, and any byte received stops it). Here a request's head must arrive whole within
`header_timeout_sec` of the connection, or of the previous answer on it, else the connection
is closed. The body's own deadline is the BodyDoor's.

The program that serves takes SIGINT and SIGTERM itself, for its whole run (`Server` takes no
signal over): uvicorn's server, and asyncio.run before it, each put a handler of their own in
place and back as they start and stop, and a gateway sent SIGINT just after its first line
under load was seen to serve on (found in CI, not reproduced since).
"""

import asyncio
import contextlib
import logging
import signal
import socket
from collections.abc import Callable, Iterator
from types import FrameType
from typing import Any
from urllib.parse import parse_qsl, urlencode

import h11
import uvicorn
from uvicorn.protocols.http.h11_impl import H11Protocol

HEADER_TIMEOUT_SEC = 10.0
KEEP_ALIVE_SEC = 5
"""An idle kept-alive connection is closed after this long (uvicorn's default)."""
MAX_HEAD_BYTES = 16 * 1024
"""A request's head (request line and headers) larger than this is refused 400 (h11's default)."""
SHUTDOWN_GRACE_SEC = 2
"""How long requests still answered may keep the server from stopping (its event streams are
ended as it begins to stop: see `Server`)."""
HIDDEN = '<removed>'


class _HeadDeadlineProtocol(H11Protocol):
    """h11, with a deadline on each request's head (see the module's docstring)."""

    header_timeout_sec = HEADER_TIMEOUT_SEC
    _head_deadline: asyncio.TimerHandle | None = None

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        super().connection_made(transport)
        self._watch_head()

    def handle_events(self) -> None:
        super().handle_events()
        self._watch_head()

    def on_response_complete(self) -> None:
        super().on_response_complete()
        self._watch_head()

    def connection_lost(self, exc: Exception | None) -> None:
        self._stop_deadline()
        super().connection_lost(exc)

    def _watch_head(self) -> None:
        """A deadline runs while a request's head is awaited (from its first wait on)."""
        if self.conn.their_state is not h11.IDLE or self.transport.is_closing():
            self._stop_deadline()
        elif self._head_deadline is None:
            self._head_deadline = self.loop.call_later(self.header_timeout_sec, self._head_late)

    def _stop_deadline(self) -> None:
        if self._head_deadline is not None:
            self._head_deadline.cancel()
            self._head_deadline = None

    def _head_late(self) -> None:
        self._head_deadline = None
        if self.conn.their_state is h11.IDLE and not self.transport.is_closing():
            self.transport.close()


def _protocol(header_timeout_sec: float) -> type[H11Protocol]:
    class Protocol(_HeadDeadlineProtocol):
        pass

    Protocol.header_timeout_sec = header_timeout_sec
    return Protocol


def without_tokens(path: str) -> str:
    """A request's path and query, with the value of each `token` parameter removed."""
    route, _, query = path.partition('?')
    if not query:
        return path
    pairs = parse_qsl(query, keep_blank_values=True)
    if not any(name == 'token' for name, _ in pairs):
        return path
    hidden = [(name, HIDDEN if name == 'token' else value) for name, value in pairs]
    return f'{route}?{urlencode(hidden, safe="<>")}'


class _TokenFilter(logging.Filter):
    """Takes the tokens out of uvicorn's access lines (their arguments: client, method,
    path with query, HTTP version, status)."""

    def filter(self, record: logging.LogRecord) -> bool:
        args = record.args
        if isinstance(args, tuple) and len(args) == 5 and isinstance(args[2], str):
            record.args = (*args[:2], without_tokens(args[2]), *args[3:])
        return True


def server_config(
    app: Any, header_timeout_sec: float = HEADER_TIMEOUT_SEC, access_log: bool = False
) -> uvicorn.Config:
    """uvicorn's settings for the gateway (warnings only; access lines with `access_log`)."""
    config = uvicorn.Config(
        app,
        http=_protocol(header_timeout_sec),
        log_level='warning',
        access_log=access_log,
        timeout_keep_alive=KEEP_ALIVE_SEC,
        h11_max_incomplete_event_size=MAX_HEAD_BYTES,
        timeout_graceful_shutdown=SHUTDOWN_GRACE_SEC,
        # the client's address is the connection's: X-Forwarded-For from a process of this
        # host would otherwise name any address (the read bound counts per address)
        proxy_headers=False,
        server_header=False,
    )
    if access_log:  # log_level 'warning' also silenced them: --access-log printed nothing
        access = logging.getLogger('uvicorn.access')
        access.setLevel(logging.INFO)
        access.addFilter(_TokenFilter())
    return config


class Server(uvicorn.Server):
    """uvicorn's server, leaving the signals to its program (see `stopped_by_signals`), which
    calls `on_stopping()` as it begins to stop: its program ends the event streams there (an
    open stream would otherwise hold the stop for SHUTDOWN_GRACE_SEC, then be cut without a
    word)."""

    def __init__(self, config: uvicorn.Config, on_stopping: Callable[[], None]) -> None:
        super().__init__(config)
        self._on_stopping = on_stopping

    async def shutdown(self, sockets: list[socket.socket] | None = None) -> None:
        self._on_stopping()
        await super().shutdown(sockets)

    @contextlib.contextmanager
    def capture_signals(self) -> Iterator[None]:
        yield


@contextlib.contextmanager
def stopped_by_signals(server: uvicorn.Server) -> Iterator[None]:
    """Within: SIGINT or SIGTERM asks `server` to stop, whether it serves yet or not (it then
    stops once started); a second SIGINT, to stop without waiting for open connections."""

    def on_signal(signum: int, _: FrameType | None) -> None:
        if server.should_exit and signum == signal.SIGINT:
            server.force_exit = True
        server.should_exit = True

    handled = (signal.SIGINT, signal.SIGTERM)
    before = {signum: signal.signal(signum, on_signal) for signum in handled}
    try:
        yield
    finally:
        for signum, handler in before.items():
            signal.signal(signum, handler)


def listen(program: str, host: str, port: int) -> socket.socket:
    """A socket listening on `host`:`port` (0: any free port); SystemExit naming `program`
    when it cannot."""
    family = socket.AF_INET6 if ':' in host else socket.AF_INET
    # IPPROTO_TCP named: asyncio sets TCP_NODELAY on the accepted connections only then; else a
    # response sent in two writes waits for the client's delayed ACK (40 ms) on a kept-alive one
    listener = socket.socket(family, socket.SOCK_STREAM, socket.IPPROTO_TCP)
    listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        listener.bind((host, port))
    except OSError as error:
        listener.close()
        raise SystemExit(f'{program}: cannot listen on {host}:{port}: {error}') from None
    listener.listen(128)
    return listener
