"""An ASGI middleware that reads a request's body before the application sees it, and refuses it
when it is too large (413), too slow (408), or JSON that is not plain (422).

The body is read whole, counted as it comes: one declared too large is refused before a byte
of it is read, one sent in chunks once it passes the limit (FastAPI turned the exception of a
counting receive into a 400). A JSON body (Content-Type JSON, or none: FastAPI parses both) is
checked by `strict_json`: nesting (RecursionError was a 400), a key given twice, NaN and
Infinity, invalid JSON or UTF-8; the application gets only bodies it can parse.
"""

import asyncio

from starlette.datastructures import Headers
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from task_manager.protocol.errors import RefusalCode
from task_manager.protocol.strict_json import RefusedJsonError, load
from task_manager_web.errors import error_response

BODY_TIMEOUT_SEC = 30.0
"""The longest a request's body may take to arrive, once its head has."""


class BodyDoor:
    def __init__(self, app: ASGIApp, max_bytes: int, timeout_sec: float = BODY_TIMEOUT_SEC) -> None:
        self.app = app
        self.max_bytes = max_bytes
        self.timeout_sec = timeout_sec

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope['type'] != 'http':
            await self.app(scope, receive, send)
            return
        headers = Headers(scope=scope)
        declared = headers.get('content-length', '0')
        if declared.isdigit() and int(declared) > self.max_bytes:
            await self._too_large(scope, receive, send)
            return
        try:
            async with asyncio.timeout(self.timeout_sec):
                body = await self._read(receive)
        except TimeoutError:
            message = f'the body did not arrive within {self.timeout_sec:g} s'
            await error_response(408, RefusalCode.BODY_TIMEOUT, message)(scope, receive, send)
            return
        if body is None:  # the client went away
            return
        if len(body) > self.max_bytes:
            await self._too_large(scope, receive, send)
            return
        if body and _parsed_as_json(headers):
            try:
                load(body)
            except RefusedJsonError as refused:
                await error_response(422, refused.code, refused.message)(scope, receive, send)
                return
        await self.app(scope, _replaying(body, receive), send)

    async def _read(self, receive: Receive) -> bytes | None:
        """The whole body, or as much as passes the limit; None if the client disconnected."""
        chunks: list[bytes] = []
        received = 0
        while True:
            message = await receive()
            if message['type'] == 'http.disconnect':
                return None
            chunk = message.get('body', b'')
            chunks.append(chunk)
            received += len(chunk)
            if received > self.max_bytes or not message.get('more_body', False):
                return b''.join(chunks)

    async def _too_large(self, scope: Scope, receive: Receive, send: Send) -> None:
        response = error_response(
            413, RefusalCode.BODY_TOO_LARGE, f'request bodies are limited to {self.max_bytes} bytes'
        )
        await response(scope, receive, send)


def _parsed_as_json(headers: Headers) -> bool:
    """Whether FastAPI would parse the body as JSON: no Content-Type, or a JSON one."""
    content_type = headers.get('content-type')
    if not content_type:
        return True
    media_type = content_type.partition(';')[0].strip().lower()
    return media_type == 'application/json' or media_type.endswith('+json')


def _replaying(body: bytes, receive: Receive) -> Receive:
    """A receive that gives the body read, then what comes after it (a disconnect)."""
    replayed = False

    async def replay() -> Message:
        nonlocal replayed
        if not replayed:
            replayed = True
            return {'type': 'http.request', 'body': body, 'more_body': False}
        return await receive()

    return replay
