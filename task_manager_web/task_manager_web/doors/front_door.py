"""An ASGI middleware, the outermost: a request must name the gateway in its `Host` header
(else 400), and every answer carries the security headers.

The Host allow-list stops DNS rebinding: a web page of another site whose name its DNS server
points at 127.0.0.1 reaches the gateway from the user's browser, with its own name as Host.
The names allowed: 127.0.0.1, localhost, [::1], the address the gateway listens on, and those
given with --allowed-host; a port is not compared.
"""

from collections.abc import Iterable

from starlette.datastructures import Headers, MutableHeaders
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from task_manager.protocol.errors import RefusalCode
from task_manager_web.errors import error_response

LOCAL_HOSTS = ('127.0.0.1', 'localhost', '::1')
# The gateway's own files only (the dashboard's and Swagger UI's at /docs): no inline script
# or style, no other site, no framing; `data:` images for the icons.
CONTENT_SECURITY_POLICY = (
    "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' data:; "
    "connect-src 'self'; form-action 'self'; base-uri 'none'; frame-ancestors 'none'"
)
SECURITY_HEADERS = {
    'Content-Security-Policy': CONTENT_SECURITY_POLICY,
    'X-Frame-Options': 'DENY',
    'X-Content-Type-Options': 'nosniff',
    # the dashboard's address holds the token until its script takes it out
    'Referrer-Policy': 'no-referrer',
}


def host_name(host: str) -> str:
    """The name in a Host header, without its port: `[::1]:8080` -> `::1`."""
    host = host.strip().lower()
    if host.startswith('['):
        return host[1:].partition(']')[0]
    return host.rpartition(':')[0] if host.count(':') == 1 else host


class FrontDoor:
    def __init__(self, app: ASGIApp, allowed_hosts: Iterable[str]) -> None:
        self.app = app
        self.allowed_hosts = tuple(dict.fromkeys(host_name(h) for h in allowed_hosts))

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope['type'] != 'http':
            await self.app(scope, receive, send)
            return

        async def send_with_headers(message: Message) -> None:
            if message['type'] == 'http.response.start':
                headers = MutableHeaders(scope=message)
                for name, value in SECURITY_HEADERS.items():
                    headers.setdefault(name, value)
            await send(message)

        host = Headers(scope=scope).get('host', '')
        if host_name(host) not in self.allowed_hosts:
            allowed = ', '.join(self.allowed_hosts)
            response = error_response(
                400,
                RefusalCode.HOST_NOT_ALLOWED,
                f'Host {host[:100]!r} is not a name of this gateway ({allowed}); start it with '
                '--allowed-host NAME to answer to another',
            )
            await response(scope, receive, send_with_headers)
            return
        await self.app(scope, receive, send_with_headers)
