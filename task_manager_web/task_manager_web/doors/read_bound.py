"""An ASGI middleware that bounds each client's reads in flight: over the bound, 429 at once.

A client is a token's holder (each named token one client by its name, each token without
a name one by itself), or, for a request without a known token, its address. The reads are
the GET requests that ask the Task Manager (`/api/active`, `/api/tasks...`,
`/api/history`); the event stream, health, the dashboard's files and the documentation are
not. The refusal is made here, before routing, so that a flood of reads costs the event loop
little: a stop or cancel sent behind 500 reads waited for them to be routed one by one (0.13
s of the 0.15 s it took).
"""

from collections import Counter

from starlette.types import ASGIApp, Receive, Scope, Send

from task_manager.protocol.errors import RefusalCode
from task_manager_web.doors.access import Access
from task_manager_web.errors import error_response

READ_PATHS = ('/api/active', '/api/tasks', '/api/history')
"""Each, and what is under it, is a read when it is a GET."""
RETRY_AFTER_SEC = 1


def is_read(scope: Scope, paths: tuple[str, ...] = READ_PATHS) -> bool:
    """Whether the request is a GET or HEAD of one of `paths` or what is under it."""
    path: str = scope['path']
    return scope['method'] in ('GET', 'HEAD') and any(
        path == prefix or path.startswith(f'{prefix}/') for prefix in paths
    )


class ReadBound:
    def __init__(
        self, app: ASGIApp, access: Access, max_reads: int, paths: tuple[str, ...] = READ_PATHS
    ) -> None:
        """`paths`: the reads bounded (the fleet console's are its own)."""
        self.app = app
        self.access = access
        self.max_reads = max_reads
        self.paths = paths
        # key: a client's key (Access.client_key), value: its reads in flight (none: no entry)
        self._in_flight: Counter[str] = Counter()

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope['type'] != 'http' or not is_read(scope, self.paths):
            await self.app(scope, receive, send)
            return
        key = self.access.client_key(scope)
        if self._in_flight[key] >= self.max_reads:
            response = error_response(
                429,
                RefusalCode.TOO_MANY_REQUESTS,
                f'at most {self.max_reads} reads in flight per client: wait for the answers '
                'before asking again',
                headers={'Retry-After': str(RETRY_AFTER_SEC)},
            )
            await response(scope, receive, send)
            return
        self._in_flight[key] += 1
        try:
            await self.app(scope, receive, send)
        finally:
            self._in_flight[key] -= 1
            if not self._in_flight[key]:
                del self._in_flight[key]
