"""Who may use the gateway: a bearer token on every request that starts, cancels or stops.

Reading needs it too unless the gateway runs with --read-without-token. The token is
compared in constant time. Only the event stream also takes it as `?token=` (a browser's
EventSource cannot send headers). A request is refused 401 with `WWW-Authenticate: Bearer`.

Each dependency answers who sent the request, a `Caller`: the source of the tasks it starts
is set here, never taken from the request, so that the history says who did it.
"""

import secrets
from dataclasses import dataclass
from typing import Annotated

from fastapi import Depends, Query, Request
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from starlette.datastructures import Headers
from starlette.types import Scope

from task_manager_web.errors import ApiError

_BEARER = HTTPBearer(auto_error=False, description='The token the gateway printed at start.')
Credentials = Annotated[HTTPAuthorizationCredentials | None, Depends(_BEARER)]
TOKEN_HOLDER = 'token'
"""The client key of the token's holder (a token has no name yet: there is one)."""


@dataclass(frozen=True)
class Caller:
    """Who sent a request."""

    source: str
    """The source of the tasks it starts: the gateway's (`WEB`), later `WEB:<token name>`."""


class Access:
    def __init__(self, token: str, read_without_token: bool = False, source: str = 'WEB') -> None:
        self._token = token
        self._read_without_token = read_without_token
        self._source = source

    def _is_token(self, given: str) -> bool:
        return secrets.compare_digest(given.encode(), self._token.encode())

    def client_key(self, scope: Scope) -> str:
        """Who a request comes from, for bounds: `token` with the token, else `address:<ip>`."""
        authorization = Headers(scope=scope).get('authorization', '')
        scheme, _, given = authorization.partition(' ')
        if scheme.lower() == 'bearer' and self._is_token(given.strip()):
            return TOKEN_HOLDER
        client = scope.get('client')
        return f'address:{client[0] if client else "unknown"}'

    def _holder(self, given: str | None) -> Caller:
        """The caller of a request that needs the token; 401 without it."""
        if not given:
            raise ApiError(
                401,
                'unauthorized',
                'missing token: send Authorization: Bearer <token>',
                headers={'WWW-Authenticate': 'Bearer'},
            )
        if not self._is_token(given):
            raise ApiError(
                401,
                'unauthorized',
                'wrong token',
                headers={'WWW-Authenticate': 'Bearer error="invalid_token"'},
            )
        return Caller(self._source)

    def writer(self, given: str | None) -> Caller:
        """Of the requests that change something."""
        return self._holder(given)

    def reader(self, given: str | None) -> Caller:
        """Of the requests that only read."""
        if self._read_without_token:
            return Caller(self._source)
        return self._holder(given)


def _access(request: Request) -> Access:
    access: Access = request.app.state.access
    return access


async def _writer(request: Request, credentials: Credentials) -> Caller:
    return _access(request).writer(credentials.credentials if credentials else None)


async def _reader(request: Request, credentials: Credentials) -> Caller:
    return _access(request).reader(credentials.credentials if credentials else None)


async def _stream_reader(
    request: Request,
    credentials: Credentials,
    token: Annotated[str | None, Query(description='The token, for EventSource.')] = None,
) -> Caller:
    return _access(request).reader(credentials.credentials if credentials else token)


Writer = Annotated[Caller, Depends(_writer)]
"""Who sent a request that changes something (needs the token)."""
Reader = Annotated[Caller, Depends(_reader)]
"""Who sent a request that only reads (needs the token unless --read-without-token)."""
StreamReader = Annotated[Caller, Depends(_stream_reader)]
"""As Reader, for the event stream: the header, or `?token=`."""
