"""Who may use the gateway: a bearer token on every request that starts, cancels or stops.

Reading needs it too unless the gateway runs with --read-without-token. The token is
compared in constant time. Only the event stream also takes it as `?token=` (a browser's
EventSource cannot send headers).
"""

import secrets
from typing import Annotated

from fastapi import Depends, Query
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

from task_manager_web.errors import ApiError

_BEARER = HTTPBearer(auto_error=False, description='The token the gateway printed at start.')
Credentials = Annotated[HTTPAuthorizationCredentials | None, Depends(_BEARER)]


class Access:
    def __init__(self, token: str, read_without_token: bool = False) -> None:
        self._token = token
        self._read_without_token = read_without_token

    def _check(self, given: str | None) -> None:
        if not given:
            raise ApiError(401, 'unauthorized', 'missing token: send Authorization: Bearer <token>')
        if not secrets.compare_digest(given.encode(), self._token.encode()):
            raise ApiError(401, 'unauthorized', 'wrong token')

    def writer(self, credentials: Credentials) -> None:
        """Dependency of the requests that change something."""
        self._check(credentials.credentials if credentials else None)

    def reader(self, credentials: Credentials) -> None:
        """Dependency of the requests that only read."""
        if not self._read_without_token:
            self._check(credentials.credentials if credentials else None)

    def stream_reader(
        self,
        credentials: Credentials,
        token: Annotated[str | None, Query(description='The token, for EventSource.')] = None,
    ) -> None:
        """Dependency of the event stream: the header, or `?token=`."""
        if not self._read_without_token:
            self._check(credentials.credentials if credentials else token)
