"""Who may do what on the gateway: a bearer token with a role (tokens.py) on every request.

Each route names the role it needs with one annotation of its caller, `Viewer`, `Operator`
(`StreamViewer` for the event stream, `MetricsViewer` for /metrics), or, for a route that runs
a system task, `runs(<the task>)`: the role of SYSTEM_TASK_ROLES
(task_roles.py), the one table of what each system task needs, however a request asks for it.
A start, a mission and a schedule then check what they start (check_need): a system task
named in a start, a mission's step or a schedule needs its own role there too, and a priority
of one's own an admin's. Reading needs a token unless the gateway runs with
--read-without-token (then anyone reads, as a viewer); /metrics needs one unless
--metrics-without-token. Tokens are compared in constant time. Only the event stream also
takes the token as `?token=` (a browser's EventSource cannot send headers). No token, or an
unknown one: 401 with `WWW-Authenticate: Bearer`; a role below what is asked: 403, nothing
done.

Each dependency answers who sent the request, a `Caller`: the source of the tasks it starts
is set here, never taken from the request (`WEB`, `WEB:<token name>` for a named token), so
that the history says who did it.
"""

import secrets
from collections.abc import Awaitable, Callable, Sequence
from dataclasses import dataclass
from typing import Annotated, Any, Literal

from fastapi import Depends, Query, Request
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from pydantic import BaseModel
from starlette.datastructures import Headers
from starlette.types import Scope

from task_manager.core.sources import door_source
from task_manager.protocol.errors import RefusalCode
from task_manager_web.doors.task_roles import (
    SYSTEM_TASK_ROLES,
    TASK_ROLE,
    Need,
    UnreadableTaskDataError,
)
from task_manager_web.doors.tokens import Role, Token
from task_manager_web.errors import ApiError

_BEARER = HTTPBearer(auto_error=False, description='A token of the gateway (its token file).')
Credentials = Annotated[HTTPAuthorizationCredentials | None, Depends(_BEARER)]


@dataclass(frozen=True)
class Caller:
    """Who sent a request."""

    role: Role
    name: str
    """The name of its token; '': a token without a name, or no token (reading without)."""
    source: str
    """The source of the tasks it starts: the gateway's (`WEB`), `WEB:<name>` for a name."""


class Identity(BaseModel):
    """Who the token is (GET /api/whoami): what the dashboard may offer its holder."""

    role: Literal['viewer', 'operator', 'admin']
    name: str


class Access:
    def __init__(
        self,
        tokens: Sequence[Token],
        read_without_token: bool = False,
        source: str = 'WEB',
        metrics_without_token: bool = False,
    ) -> None:
        self._tokens = tuple(tokens)
        self._read_without_token = read_without_token
        self._source = source
        self._metrics_without_token = metrics_without_token

    def _find(self, given: str) -> Token | None:
        """The token `given` is; compared with every token in constant time."""
        found = None
        for token in self._tokens:
            if secrets.compare_digest(given.encode(), token.secret.encode()):
                found = token
        return found

    def client_key(self, scope: Scope) -> str:
        """Who a request comes from, for bounds: its token's key, else `address:<ip>`."""
        authorization = Headers(scope=scope).get('authorization', '')
        scheme, _, given = authorization.partition(' ')
        token = self._find(given.strip()) if scheme.lower() == 'bearer' else None
        if token is not None:
            return token.key
        client = scope.get('client')
        return f'address:{client[0] if client else "unknown"}'

    def caller(self, given: str | None, needed: Role, what: str) -> Caller:
        """The caller of `what` (a request), which needs role `needed`: 401 without a
        known token (a viewer's reads excepted with --read-without-token), 403 below it."""
        token = self._find(given) if given else None
        if token is None and needed is Role.VIEWER and self._read_without_token:
            return Caller(Role.VIEWER, '', self._source)
        holder = self._holder(given, token)
        if holder.role < needed:
            raise forbidden(what, needed, holder.role)
        return self._caller_of(holder)

    def metrics_caller(self, given: str | None) -> Caller | None:
        """A viewer, even with --read-without-token; None with --metrics-without-token."""
        if self._metrics_without_token:
            return None
        return self._caller_of(self._holder(given, self._find(given) if given else None))

    def _caller_of(self, token: Token) -> Caller:
        return Caller(token.role, token.name, door_source(self._source, token.name))

    @staticmethod
    def _holder(given: str | None, token: Token | None) -> Token:
        """The token of a request that needs one; 401 without it."""
        if not given:
            raise ApiError(
                401,
                RefusalCode.UNAUTHORIZED,
                'missing token: send Authorization: Bearer <token>',
                headers={'WWW-Authenticate': 'Bearer'},
            )
        if token is None:
            raise ApiError(
                401,
                RefusalCode.UNAUTHORIZED,
                'wrong token',
                headers={'WWW-Authenticate': 'Bearer error="invalid_token"'},
            )
        return token


def forbidden(what: str, needed: Role, role: Role, field: str = '', hint: str = '') -> ApiError:
    """403 for `what`, beyond a caller of `role`."""
    message = f'{what} needs role {needed.label}; this token is {role.label}'
    return ApiError(403, RefusalCode.FORBIDDEN, message + (f' ({hint})' if hint else ''), field)


def check_need(caller: Caller, needed: Callable[[], Need]) -> None:
    """403 when what `needed` says a request asks for needs a role above the caller's; 422
    when it cannot be known (a task_data in JSON text that is not plain JSON)."""
    try:
        need = needed()
    except UnreadableTaskDataError as unreadable:
        raise ApiError(
            422, RefusalCode.INVALID_REQUEST, str(unreadable), unreadable.field
        ) from None
    if caller.role < need.role:
        raise forbidden(need.what, need.role, caller.role, field=need.field)


def check_start_priority(caller: Caller, priority: int | None) -> None:
    """A start that gives its own priority decides what it pre-empts and overtakes in the
    queue, as reprioritize does: an admin's; an operator's start leaves it out, and runs at
    the task's declared priority plus its source's (`source_priorities`)."""
    if priority is not None and caller.role < Role.ADMIN:
        raise forbidden(
            'a start that gives a priority',
            Role.ADMIN,
            caller.role,
            field='priority',
            hint="leave priority out: the task's declared priority applies",
        )


def _access(request: Request) -> Access:
    access: Access = request.app.state.access
    return access


def _what(request: Request) -> str:
    return f'{request.method} {request.url.path}'


def _needs(role: Role) -> Callable[[Request, Credentials], Awaitable[Caller]]:
    """The dependency of a route that needs `role` (the token in the header)."""

    async def caller(request: Request, credentials: Credentials) -> Caller:
        given = credentials.credentials if credentials else None
        return _access(request).caller(given, role, _what(request))

    return caller


async def _stream_viewer(
    request: Request,
    credentials: Credentials,
    token: Annotated[str | None, Query(description='The token, for EventSource.')] = None,
) -> Caller:
    given = credentials.credentials if credentials else token
    return _access(request).caller(given, Role.VIEWER, _what(request))


async def _metrics_viewer(request: Request, credentials: Credentials) -> Caller | None:
    given = credentials.credentials if credentials else None
    return _access(request).metrics_caller(given)


def runs(task_name: str) -> Any:
    """The dependency of a route that runs system task `task_name`: the role the table gives
    it (`caller: Annotated[Caller, runs(REPRIORITIZE)]`)."""
    return Depends(_needs(SYSTEM_TASK_ROLES[task_name]))


Viewer = Annotated[Caller, Depends(_needs(Role.VIEWER))]
"""A request that only reads (any token; none needed with --read-without-token)."""
Operator = Annotated[Caller, Depends(_needs(TASK_ROLE))]
"""A request that starts a task (what it starts is checked then), or answers a confirmation."""
StreamViewer = Annotated[Caller, Depends(_stream_viewer)]
"""As Viewer, for the event stream: the header, or `?token=`."""
MetricsViewer = Annotated[Caller | None, Depends(_metrics_viewer)]
"""GET /metrics: any token, even with --read-without-token; None with --metrics-without-token."""
