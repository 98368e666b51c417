"""Tools of the tests of the doors, the web gateway's and the fleet console's alike (no rclpy
here): a token for each role and their file, a table of routes and roles walked over HTTP, and
the page in Debian's headless Chromium (driven by Playwright, which never downloads one): the
fixtures `browser` and `blank_page`, which a conftest.py or test module takes by importing them."""

import shutil
import ssl
from collections.abc import Iterator, Mapping
from functools import cache
from typing import TYPE_CHECKING, Any

import httpx
import pytest
from fastapi import FastAPI
from starlette.routing import Mount, Route

if TYPE_CHECKING:  # the page's tests only: the rest runs without a browser
    from playwright.sync_api import Browser, Page

VIEWER, OPERATOR, ADMIN = 'viewer', 'operator', 'admin'
PUBLIC = None
"""The role of a route anyone may use."""
RANKS = {VIEWER: 1, OPERATOR: 2, ADMIN: 3}
CALLERS = (None, VIEWER, OPERATOR, ADMIN)
"""Who sends a request: no token, or the token of a role."""
TOKENS = {
    VIEWER: 'viewer-token-0123456789',
    OPERATOR: 'operator-token-0123456789',
    ADMIN: 'admin-token-0123456789',
}
"""key: a role, value: its token in TOKEN_FILE."""
NAMES = {VIEWER: 'victor', OPERATOR: 'alice', ADMIN: ''}
"""key: a role, value: the name of its token in TOKEN_FILE."""
TOKEN_FILE = f"""# the tokens of the doors' tests
viewer   {TOKENS[VIEWER]}   {NAMES[VIEWER]}
operator {TOKENS[OPERATOR]} {NAMES[OPERATOR]}   # the operator of the tests

admin    {TOKENS[ADMIN]}
"""
EVENTS_PATH = '/api/events'
PAGE_TIMEOUT_SEC = 20.0
"""How long a page's test waits for what the page should show."""
CHROMIUM = shutil.which('chromium') or '/usr/bin/chromium'
# No background connections: this machine's network is closed, and the tests need none.
CHROMIUM_ARGS = [
    '--no-sandbox',
    '--disable-gpu',
    '--disable-quic',
    '--no-first-run',
    '--disable-background-networking',
    '--disable-component-update',
    '--disable-sync',
]


def client_of(url: str, role: str | None, timeout_sec: float) -> httpx.Client:
    """An HTTP client of the doors at `url` with the token of `role` (None: no token)."""
    headers = {'Authorization': f'Bearer {TOKENS[role]}'} if role else {}
    return httpx.Client(base_url=url, headers=headers, timeout=timeout_sec, verify=_tls_context())


@cache
def _tls_context() -> ssl.SSLContext:
    """One TLS context for every client of the process: httpx builds one for each client it
    makes otherwise, loading the certificate store each time (40 ms of CPU; the tables of
    routes and roles make about 450 clients a run)."""
    return httpx.create_ssl_context()


def routes_of(app: FastAPI) -> set[tuple[str, str]]:
    """(method, path) of every route of `app` ('MOUNT' for a folder of files; '?' and the
    route for one of another kind)."""
    routes = set()
    for route in app.routes:
        if isinstance(route, Mount):
            routes.add(('MOUNT', route.path))
        elif isinstance(route, Route):
            routes.update((method, route.path) for method in (route.methods or set()) - {'HEAD'})
        else:
            routes.add(('?', repr(route)))
    return routes


def route_cases(route_roles: Mapping[tuple[str, str], str | None]) -> list[Any]:
    """Every route of the table (key: method and path, value: the role it needs) with every
    caller, as pytest parameters (method, path, needed, caller); folders of files left out."""
    return [
        pytest.param(method, path, needed, caller, id=f'{method} {path} as {caller or "nobody"}')
        for (method, path), needed in route_roles.items()
        if method != 'MOUNT'
        for caller in CALLERS
    ]


def request(client: httpx.Client, method: str, url: str) -> httpx.Response:
    """`method url`, with `{}` for a body (what it holds is checked after the role); of the
    event stream, whose answer never ends, its head only, or its error."""
    if url == EVENTS_PATH:
        with client.stream(method, url) as response:
            if response.status_code != 200:
                response.read()
            return response
    return client.request(method, url, json={} if method in ('POST', 'PATCH') else None)


def check_role_answer(
    response: httpx.Response, method: str, url: str, needed: str | None, caller: str | None
) -> None:
    """The answer of `method url` by `caller`, to a route that needs the role `needed`: let in
    (anything but 401 and 403) at that role or above; else 401 `unauthorized` without a token,
    403 `forbidden` naming the role needed and the token's."""
    if needed is PUBLIC or (caller and RANKS[caller] >= RANKS[needed]):
        assert response.status_code not in (401, 403), response.text
    elif caller is None:
        assert response.status_code == 401, response.text
        assert response.json()['error']['code'] == 'unauthorized'
    else:
        assert response.status_code == 403, response.text
        assert response.json()['error'] == {
            'code': 'forbidden',
            'message': f'{method} {url} needs role {needed}; this token is {caller}',
            'field': '',
        }


@pytest.fixture(scope='module')
def browser() -> Iterator['Browser']:
    """Debian's headless Chromium, for the tests of a module."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield browser
        browser.close()


@pytest.fixture
def blank_page(browser: 'Browser') -> Iterator['Page']:
    """A new page, each `expect` on it waiting at most PAGE_TIMEOUT_SEC; its script errors and
    what its Content-Security-Policy refused fail the test."""
    from playwright.sync_api import expect

    expect.set_options(timeout=int(PAGE_TIMEOUT_SEC * 1000))
    context = browser.new_context(viewport={'width': 1280, 'height': 900})
    page = context.new_page()
    errors: list[str] = []
    page.on('pageerror', lambda error: errors.append(str(error)))
    page.on(
        'console',
        lambda message: (
            errors.append(message.text) if 'Content Security Policy' in message.text else None
        ),
    )
    yield page
    context.close()
    assert not errors, errors
